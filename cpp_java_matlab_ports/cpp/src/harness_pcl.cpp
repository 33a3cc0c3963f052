// Runs the PCL port on the shared test vectors: harness_pcl VECTORS_DIR
#include "flowtrack/rigid_icp.hpp"
#include "harness_common.hpp"

using harness::json;

namespace {

json rigid_icp(const json& in) {
    const Eigen::MatrixX3d source = harness::to_matrix(in.at("source"));
    const Eigen::MatrixX3d target = harness::to_matrix(in.at("target"));
    const Eigen::Matrix4d T = flowtrack::rigid_icp_pcl(source, target, in.at("threshold").get<double>(),
                                                       in.at("max_iter").get<int>());
    // compared with the reference's open3d transform "T" (T_true is informational)
    return {{"T", harness::from_matrix(T)}};
}

}  // namespace

int main(int argc, char** argv) { return harness::main_with(argc, argv, {{"rigid_icp", rigid_icp}}); }
