// Runs the Eigen port on the shared test vectors: harness_eigen VECTORS_DIR [PROBLEM ...]
#include <algorithm>

#include "flowtrack/flowtrack.hpp"
#include "harness_common.hpp"

using harness::json;

namespace {

json kalman_cv2d(const json& in) {
    const Eigen::Vector4d x0 = harness::to_vector(in.at("x0"));
    const Eigen::Matrix4d P0 = harness::to_matrix(in.at("P0"));
    flowtrack::KalmanFilterCV2D kf(in.at("dt").get<double>(), in.at("process_var").get<double>(),
                                   in.at("meas_var").get<double>(), x0, P0);
    const Eigen::MatrixXd Z = harness::to_matrix(in.at("measurements"));
    Eigen::MatrixXd positions(Z.rows(), 2);
    for (Eigen::Index t = 0; t < Z.rows(); ++t) {
        kf.predict();
        kf.update(Z.row(t).transpose());
        positions.row(t) = kf.position().transpose();
    }
    return {{"positions", harness::from_matrix(positions)}, {"P_final", harness::from_matrix(kf.P)}};
}

json white_noise_q(const json& in) {
    return {{"Q", harness::from_matrix(flowtrack::white_noise_q(in.at("dt").get<double>(), in.at("q").get<double>(),
                                                               in.at("dim").get<int>()))}};
}

json projection_jacobian(const json& in) {
    const Eigen::Vector3d X = harness::to_vector(in.at("X"));
    return {{"J", harness::from_matrix(flowtrack::projection_jacobian(X, in.at("fx").get<double>(),
                                                                     in.at("fy").get<double>(),
                                                                     in.at("cx").get<double>(),
                                                                     in.at("cy").get<double>()))}};
}

json mahalanobis_assignment(const json& in) {
    const Eigen::MatrixXd z_pred = harness::to_matrix(in.at("z_pred"));
    std::vector<Eigen::MatrixXd> S;
    for (const json& s : in.at("S")) S.push_back(harness::to_matrix(s));
    const Eigen::MatrixXd Z = harness::to_matrix(in.at("detections"));
    const Eigen::MatrixXd cost = flowtrack::mahalanobis_cost(z_pred, S, Z);
    json matches = json::array();
    for (const auto& [i, j] : flowtrack::assign(cost, in.at("gate").get<double>())) matches.push_back({i, j});
    return {{"cost", harness::from_matrix(cost)}, {"matches", matches}};
}

json graph_scene_flow(const json& in) {
    const Eigen::MatrixX3d X = harness::to_matrix(in.at("points"));
    const Eigen::MatrixX3d Y = harness::to_matrix(in.at("targets"));
    Eigen::SparseMatrix<double> W;
    if (in.contains("edges")) {
        std::vector<Eigen::Triplet<double>> trips;
        for (const json& e : in.at("edges")) {
            const int i = e.at(0).get<int>(), j = e.at(1).get<int>();
            const double w = e.at(2).get<double>();
            trips.emplace_back(i, j, w);
            trips.emplace_back(j, i, w);
        }
        W.resize(X.rows(), X.rows());
        W.setFromTriplets(trips.begin(), trips.end());
    } else {
        W = flowtrack::knn_graph(X, in.at("k").get<int>(), in.at("sigma").get<double>());
    }
    const Eigen::MatrixX3d V =
        flowtrack::graph_scene_flow(X, Y, in.at("dt").get<double>(), in.at("lam").get<double>(), W);
    return {{"flow", harness::from_matrix(V)}};
}

json variational_scene_flow(const json& in) {
    const json& a = in.at("a");
    const json& b = in.at("b");
    if (a.size() != b.size()) throw std::invalid_argument("a and b must have the same components");
    json v = json::array();
    for (size_t c = 0; c < a.size(); ++c)
        v.push_back(harness::from_matrix(flowtrack::variational_component(
            harness::to_matrix(a[c]), harness::to_matrix(b[c]), in.at("dt").get<double>(),
            in.at("lam").get<double>())));
    return {{"v", v}};
}

}  // namespace

int main(int argc, char** argv) {
    return harness::main_with(argc, argv,
                              {{"kalman_cv2d", kalman_cv2d},
                               {"white_noise_q", white_noise_q},
                               {"projection_jacobian", projection_jacobian},
                               {"mahalanobis_assignment", mahalanobis_assignment},
                               {"graph_scene_flow", graph_scene_flow},
                               {"variational_scene_flow", variational_scene_flow}});
}
