// flowtrack exercise harness (C++): reads a vectors file, calls your functions, prints the outputs.
//
//   harness CASES.json            prints  OUTPUT <case id> <json of the outputs>  per case
//   harness --check PUBLIC.json   also compares with each case's "expected" (|got - exp| <= atol +
//                                 rtol |exp|) and prints  CASE <problem> <id> PASS|FAIL <err> <message>
//
// The file format is the course's shared vectors format:
//   {"problem": ..., "cases": [{"id", "input": {...}, "expected": {...}, "rtol", "atol"}, ...]}
// Compiled with -DFT_PROBLEM_<problem>; do not edit (the grader uses its own copy).
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "exercise.hpp"

using json = nlohmann::json;

static Eigen::MatrixXd mat(const json& j) {
    if (!j.is_array()) throw std::runtime_error("expected a matrix");
    const Eigen::Index rows = static_cast<Eigen::Index>(j.size());
    const Eigen::Index cols = rows ? static_cast<Eigen::Index>(j[0].size()) : 0;
    Eigen::MatrixXd m(rows, cols);
    for (Eigen::Index i = 0; i < rows; ++i)
        for (Eigen::Index k = 0; k < cols; ++k) m(i, k) = j.at(i).at(k).get<double>();
    return m;
}

static Eigen::VectorXd vec(const json& j) {
    if (!j.is_array()) throw std::runtime_error("expected a vector");
    Eigen::VectorXd v(static_cast<Eigen::Index>(j.size()));
    for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = j.at(i).get<double>();
    return v;
}

template <typename M>
static json out_mat(const M& m) {
    json j = json::array();
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
        json row = json::array();
        for (Eigen::Index k = 0; k < m.cols(); ++k) row.push_back(static_cast<double>(m(i, k)));
        j.push_back(row);
    }
    return j;
}

template <typename V>
static json out_vec(const V& v) {
    json j = json::array();
    for (Eigen::Index i = 0; i < v.size(); ++i) j.push_back(static_cast<double>(v(i)));
    return j;
}

static json solve(const json& in) {
#if defined(FT_PROBLEM_cv_model)
    Eigen::Matrix4d F = Eigen::Matrix4d::Zero(), Q = Eigen::Matrix4d::Zero();
    cv_model(in.at("dt").get<double>(), in.at("q").get<double>(), F, Q);
    return {{"F", out_mat(F)}, {"Q", out_mat(Q)}};
#elif defined(FT_PROBLEM_kalman_step)
    Eigen::VectorXd x = vec(in.at("x"));
    Eigen::MatrixXd P = mat(in.at("P"));
    kalman_step(x, P, mat(in.at("F")), mat(in.at("Q")), mat(in.at("H")), mat(in.at("R")), vec(in.at("z")));
    return {{"x", out_vec(x)}, {"P", out_mat(P)}};
#elif defined(FT_PROBLEM_projection_jacobian)
    const Eigen::VectorXd X = vec(in.at("X"));
    if (X.size() != 3) throw std::runtime_error("X must have 3 entries");
    const Eigen::Matrix<double, 2, 3> J = projection_jacobian(Eigen::Vector3d(X), in.at("fx").get<double>(),
        in.at("fy").get<double>(), in.at("cx").get<double>(), in.at("cy").get<double>());
    return {{"J", out_mat(J)}};
#elif defined(FT_PROBLEM_mahalanobis_gating)
    const Eigen::VectorXd d2 = mahalanobis_d2(vec(in.at("z_pred")), mat(in.at("S")), mat(in.at("Z")));
    const Eigen::VectorXi inside = gate(d2, in.at("gate").get<double>());
    return {{"d2", out_vec(d2)}, {"inside", out_vec(inside)}};
#elif defined(FT_PROBLEM_assignment)
    const Eigen::MatrixXd C = mat(in.at("C"));
    if (C.rows() > C.cols()) throw std::runtime_error("C must have at least as many columns as rows");
    const std::vector<int> a = assignment(C);
    json out = json::array();
    for (int j : a) out.push_back(static_cast<double>(j));
    return {{"assignment", out}};
#else
#error "compile with -DFT_PROBLEM_<problem>"
#endif
}

// worst |got - exp| over the expected outputs, and whether every entry is within tolerance
static bool compare(const json& got, const json& exp, double rtol, double atol, double& worst, std::string& msg) {
    if (exp.is_number()) {
        if (!got.is_number()) { msg = "not a number"; return false; }
        const double g = got.get<double>(), e = exp.get<double>(), err = std::fabs(g - e);
        worst = std::isnan(err) ? INFINITY : std::max(worst, err);
        if (!(err <= atol + rtol * std::fabs(e))) {
            std::ostringstream s;
            s.precision(17);
            s << "got " << g << ", expected " << e;
            msg = s.str();
            return false;
        }
        return true;
    }
    if (!got.is_array() || got.size() != exp.size()) { msg = "wrong shape"; return false; }
    bool ok = true;
    for (std::size_t i = 0; i < exp.size(); ++i) {
        std::string m;
        if (!compare(got[i], exp[i], rtol, atol, worst, m) && ok) { ok = false; msg = "[" + std::to_string(i) + "]" + m; }
    }
    return ok;
}

int main(int argc, char** argv) {
    const bool check = argc == 3 && std::string(argv[1]) == "--check";
    if (argc != 2 && !check) {
        std::cerr << "usage: harness [--check] CASES.json\n";
        return 2;
    }
    std::ifstream f(argv[argc - 1]);
    if (!f) { std::cerr << "cannot read " << argv[argc - 1] << "\n"; return 2; }
    const json doc = json::parse(f);
    const std::string problem = doc.value("problem", std::string("?"));
    std::cout.precision(17);
    bool all_ok = true;
    for (const json& c : doc.at("cases")) {
        const std::string id = c.at("id").get<std::string>();
        json got;
        try {
            got = solve(c.at("input"));
        } catch (const std::exception& e) {
            std::cout << "ERROR " << id << " " << e.what() << std::endl;
            all_ok = false;
            continue;
        }
        std::cout << "OUTPUT " << id << " " << got.dump() << std::endl;
        if (check) {
            double worst = 0.0;
            std::string msg = "ok";
            bool ok = true;
            for (auto it = c.at("expected").begin(); it != c.at("expected").end(); ++it) {
                std::string m;
                if (!got.contains(it.key())) { ok = false; msg = it.key() + " missing"; continue; }
                if (!compare(got[it.key()], it.value(), c.at("rtol").get<double>(), c.at("atol").get<double>(), worst, m) && ok) {
                    ok = false;
                    msg = it.key() + m;
                }
            }
            all_ok = all_ok && ok;
            std::cout << "CASE " << problem << " " << id << (ok ? " PASS " : " FAIL ") << worst << " " << msg << std::endl;
        }
    }
    return check && !all_ok ? 1 : 0;
}
