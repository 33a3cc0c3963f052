// Unit test of the PCL port: ICP recovers a known rigid motion of a noise-free box cloud.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "flowtrack/rigid_icp.hpp"

TEST(Pcl, IcpRecoversKnownMotion) {
    std::mt19937 gen(2);
    std::uniform_real_distribution<double> u(-0.5, 0.5);
    std::uniform_int_distribution<int> face(0, 5);
    const Eigen::Vector3d size(0.12, 0.08, 0.05);
    const int n = 500;
    Eigen::MatrixX3d X(n, 3);
    for (int i = 0; i < n; ++i) {
        Eigen::Vector3d p(u(gen), u(gen), u(gen));
        const int f = face(gen);
        p(f % 3) = f < 3 ? 0.5 : -0.5;
        X.row(i) = p.cwiseProduct(size).transpose() + Eigen::RowVector3d(0, 0, 0.8);
    }
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.block<3, 3>(0, 0) = Eigen::AngleAxisd(0.06, Eigen::Vector3d(0.3, 0.2, 1.0).normalized()).toRotationMatrix();
    T.block<3, 1>(0, 3) = Eigen::Vector3d(0.01, -0.004, 0.002) + Eigen::Vector3d(0, 0, 0.8) -
                          T.block<3, 3>(0, 0) * Eigen::Vector3d(0, 0, 0.8);
    const Eigen::MatrixX3d Y = (X * T.block<3, 3>(0, 0).transpose()).rowwise() + T.block<3, 1>(0, 3).transpose();
    const Eigen::Matrix4d E = flowtrack::rigid_icp_pcl(X, Y, 0.05, 100);
    EXPECT_LT((E - T).cwiseAbs().maxCoeff(), 1e-5);
    const Eigen::MatrixX3d flow = flowtrack::rigid_flow(E, X, 0.1);
    EXPECT_LT(((Y - X) / 0.1 - flow).cwiseAbs().maxCoeff(), 1e-4);
}
