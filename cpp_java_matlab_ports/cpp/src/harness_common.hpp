// Shared harness code: read a vector file, run every case, compare with the case's tolerance and
// print one line per case:  CASE <problem> <case_id> PASS|FAIL <max_abs_error> <message>
#pragma once

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace harness {

using nlohmann::json;

inline Eigen::MatrixXd to_matrix(const json& rows) {
    const Eigen::Index n = static_cast<Eigen::Index>(rows.size());
    const Eigen::Index m = n ? static_cast<Eigen::Index>(rows.at(0).size()) : 0;
    Eigen::MatrixXd A(n, m);
    for (Eigen::Index i = 0; i < n; ++i) {
        if (static_cast<Eigen::Index>(rows.at(i).size()) != m) throw std::invalid_argument("ragged matrix");
        for (Eigen::Index j = 0; j < m; ++j) A(i, j) = rows.at(i).at(j).get<double>();
    }
    return A;
}

inline Eigen::VectorXd to_vector(const json& values) {
    Eigen::VectorXd v(static_cast<Eigen::Index>(values.size()));
    for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = values.at(i).get<double>();
    return v;
}

template <typename Derived>
json from_matrix(const Eigen::MatrixBase<Derived>& A) {
    json rows = json::array();
    for (Eigen::Index i = 0; i < A.rows(); ++i) {
        json row = json::array();
        for (Eigen::Index j = 0; j < A.cols(); ++j) row.push_back(A(i, j));
        rows.push_back(row);
    }
    return rows;
}

struct Outcome {
    bool ok = true;
    double max_err = 0.0;
    std::string msg;
};

// Elementwise |got - expected| <= atol + rtol |expected| over nested arrays of numbers.
inline void compare(const json& expected, const json& got, double rtol, double atol, const std::string& path,
                    Outcome& out) {
    if (expected.is_array()) {
        if (!got.is_array() || got.size() != expected.size()) {
            out.ok = false;
            out.max_err = NAN;
            if (out.msg.empty()) out.msg = "shape mismatch at " + path;
            return;
        }
        for (size_t i = 0; i < expected.size(); ++i)
            compare(expected[i], got[i], rtol, atol, path + "[" + std::to_string(i) + "]", out);
        return;
    }
    if (!expected.is_number() || !got.is_number()) {
        out.ok = false;
        out.max_err = NAN;
        if (out.msg.empty()) out.msg = "not a number at " + path;
        return;
    }
    const double e = expected.get<double>(), g = got.get<double>();
    const double err = std::fabs(g - e);
    if (!(err <= atol + rtol * std::fabs(e))) {
        if (out.ok || err > out.max_err) {
            std::ostringstream s;
            s.precision(17);
            s << "worst mismatch at " << path << ": got " << g << " expected " << e;
            out.msg = s.str();
        }
        out.ok = false;
    }
    if (!std::isnan(out.max_err) && (err > out.max_err || std::isnan(err))) out.max_err = err;
}

// Runs every case of <dir>/<problem>.json through `solve` (input -> object of outputs) and compares
// the keys it returns with the case's expected values. Returns the number of failed cases, or -1
// when the file is missing or unreadable.
inline int run_problem(const std::string& dir, const std::string& problem,
                       const std::function<json(const json&)>& solve) {
    const std::string path = dir + "/" + problem + ".json";
    std::ifstream in(path);
    if (!in) {
        std::cerr << "harness: missing vector file " << path << "\n";
        return -1;
    }
    json doc;
    try {
        in >> doc;
    } catch (const std::exception& e) {
        std::cerr << "harness: cannot parse " << path << ": " << e.what() << "\n";
        return -1;
    }
    int failed = 0;
    for (const json& c : doc.at("cases")) {
        const std::string id = c.at("id").get<std::string>();
        Outcome out;
        try {
            const json got = solve(c.at("input"));
            const double rtol = c.at("rtol").get<double>(), atol = c.at("atol").get<double>();
            for (auto it = got.begin(); it != got.end(); ++it) {
                if (!c.at("expected").contains(it.key())) throw std::runtime_error("no expected " + it.key());
                compare(c.at("expected").at(it.key()), it.value(), rtol, atol, it.key(), out);
            }
        } catch (const std::exception& e) {
            out.ok = false;
            out.max_err = NAN;
            out.msg = std::string("error: ") + e.what();
        }
        failed += out.ok ? 0 : 1;
        char err[32];
        if (std::isnan(out.max_err))
            std::snprintf(err, sizeof err, "nan");
        else
            std::snprintf(err, sizeof err, "%.3e", out.max_err);
        std::cout << "CASE " << problem << " " << id << " " << (out.ok ? "PASS" : "FAIL") << " " << err << " "
                  << out.msg << "\n";
    }
    return failed;
}

// main() helper: runs the given problems (all of `table`, or those named on the command line).
inline int main_with(int argc, char** argv,
                     const std::vector<std::pair<std::string, std::function<json(const json&)>>>& table) {
    if (argc < 2) {
        std::cerr << "usage: " << argv[0] << " VECTORS_DIR [PROBLEM ...]\n";
        return 2;
    }
    const std::string dir = argv[1];
    std::vector<std::string> wanted(argv + 2, argv + argc);
    int status = 0;
    for (const auto& [name, solve] : table) {
        if (!wanted.empty() && std::find(wanted.begin(), wanted.end(), name) == wanted.end()) continue;
        const int failed = run_problem(dir, name, solve);
        if (failed < 0) status = 2;
        else if (failed > 0 && status == 0) status = 1;
    }
    return status;
}

}  // namespace harness
