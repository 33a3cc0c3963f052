// Unit tests of the Eigen port against independent oracles (closed forms, finite differences,
// brute force, dense solves). Run by ctest.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>

#include "flowtrack/flowtrack.hpp"

using flowtrack::KalmanFilterCV2D;

TEST(Eigen, WhiteNoiseQIsKroneckerNotBlockDiagonal) {
    const double dt = 0.5, q = 2.0;
    const Eigen::MatrixXd Q = flowtrack::white_noise_q(dt, q, 2);
    // px-vx covariance is q dt^3/2; px-py are uncorrelated; py has the position variance q dt^4/4
    EXPECT_DOUBLE_EQ(Q(0, 2), q * std::pow(dt, 3) / 2);
    EXPECT_DOUBLE_EQ(Q(0, 1), 0.0);
    EXPECT_DOUBLE_EQ(Q(1, 1), q * std::pow(dt, 4) / 4);
    EXPECT_DOUBLE_EQ(Q(3, 3), q * dt * dt);
    // the syllabus' blkdiag(Q1d, Q1d) differs
    Eigen::Matrix2d Q1d;
    Q1d << std::pow(dt, 4) / 4, std::pow(dt, 3) / 2, std::pow(dt, 3) / 2, dt * dt;
    Eigen::Matrix4d blk = Eigen::Matrix4d::Zero();
    blk.block<2, 2>(0, 0) = q * Q1d;
    blk.block<2, 2>(2, 2) = q * Q1d;
    EXPECT_GT((Q - blk).cwiseAbs().maxCoeff(), 0.1 * q * dt * dt);
    // Q = E[w w^T] with w = G a, G = [dt^2/2 I; dt I], a ~ N(0, q I)
    Eigen::Matrix<double, 6, 3> G;
    G << dt * dt / 2, 0, 0, 0, dt * dt / 2, 0, 0, 0, dt * dt / 2, dt, 0, 0, 0, dt, 0, 0, 0, dt;
    EXPECT_LT((flowtrack::white_noise_q(dt, q, 3) - q * G * G.transpose()).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Eigen, KalmanWithoutProcessNoiseIsBatchLeastSquares) {
    // q = 0: x_T = F^T x_0 exactly, so the filter's posterior mean must equal the Bayesian
    // least-squares estimate  (P0^-1 + sum A_t^T R^-1 A_t)^-1 (P0^-1 x0 + sum A_t^T R^-1 z_t)
    // of x_0 (A_t = H F^t), propagated by F^T.
    const double dt = 0.2, r = 0.5;
    std::mt19937 gen(7);
    std::normal_distribution<double> nd;
    Eigen::Vector4d x0(0.3, -0.2, 0.1, 0.05);
    Eigen::Matrix4d P0 = Eigen::Matrix4d::Identity() * 10.0;
    KalmanFilterCV2D kf(dt, 0.0, r, x0, P0);
    Eigen::Matrix4d info = P0.inverse();
    Eigen::Vector4d rhs = P0.inverse() * x0;
    Eigen::Matrix4d Ft = Eigen::Matrix4d::Identity();
    const int T = 12;
    for (int t = 1; t <= T; ++t) {
        Ft = kf.F * Ft;
        const Eigen::Vector2d z(1.0 + 0.5 * t * dt + nd(gen), -0.3 * t * dt + nd(gen));
        kf.predict();
        kf.update(z);
        const Eigen::Matrix<double, 2, 4> A = kf.H * Ft;
        info += A.transpose() * A / r;
        rhs += A.transpose() * z / r;
    }
    const Eigen::Vector4d x_ls = Ft * info.ldlt().solve(rhs);
    const Eigen::Matrix4d P_ls = Ft * info.inverse() * Ft.transpose();
    EXPECT_LT((kf.x - x_ls).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((kf.P - P_ls).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Eigen, ProjectionJacobianMatchesCentralDifferences) {
    const double fx = 525, fy = 500, cx = 319.5, cy = 239.5, h = 1e-6;
    const Eigen::Vector3d X(0.2, -0.1, 1.3);
    const auto pi = [&](const Eigen::Vector3d& P) {
        return Eigen::Vector2d(fx * P.x() / P.z() + cx, fy * P.y() / P.z() + cy);
    };
    const Eigen::Matrix<double, 2, 3> J = flowtrack::projection_jacobian(X, fx, fy, cx, cy);
    for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d e = Eigen::Vector3d::Zero();
        e(k) = h;
        const Eigen::Vector2d d = (pi(X + e) - pi(X - e)) / (2 * h);
        EXPECT_LT((J.col(k) - d).cwiseAbs().maxCoeff(), 1e-5);
    }
    EXPECT_THROW(flowtrack::projection_jacobian(Eigen::Vector3d(0, 0, -1), fx, fy, cx, cy), std::invalid_argument);
}

TEST(Eigen, MahalanobisCostMatchesExplicitInverse) {
    Eigen::MatrixXd zp(2, 2), Z(3, 2);
    zp << 0, 0, 1, 2;
    Z << 1, 0, 0, 1, 2, 2;
    Eigen::Matrix2d S0, S1;
    S0 << 2, 0.5, 0.5, 1;
    S1 << 1, 0, 0, 4;
    const Eigen::MatrixXd C = flowtrack::mahalanobis_cost(zp, {S0, S1}, Z);
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 3; ++j) {
            const Eigen::Vector2d d = (Z.row(j) - zp.row(i)).transpose();
            const Eigen::Matrix2d S = i == 0 ? S0 : S1;
            EXPECT_NEAR(C(i, j), d.dot(S.inverse() * d), 1e-13);
        }
}

namespace {
// exhaustive search: the most admissible pairs, then the least total cost
std::pair<int, double> brute(const Eigen::MatrixXd& c, double gate) {
    std::pair<int, double> best{0, 0.0};
    std::function<void(int, std::vector<char>&, int, double)> rec = [&](int i, std::vector<char>& used, int k,
                                                                         double tot) {
        if (i == c.rows()) {
            if (k > best.first || (k == best.first && tot < best.second)) best = {k, tot};
            return;
        }
        rec(i + 1, used, k, tot);
        for (int j = 0; j < c.cols(); ++j)
            if (!used[j] && c(i, j) <= gate) {
                used[j] = 1;
                rec(i + 1, used, k + 1, tot + c(i, j));
                used[j] = 0;
            }
    };
    std::vector<char> used(c.cols(), 0);
    rec(0, used, 0, 0.0);
    return best;
}
}  // namespace

TEST(Eigen, GatedAssignmentMatchesBruteForce) {
    std::mt19937 gen(3);
    std::uniform_real_distribution<double> u(0.0, 20.0);
    for (int trial = 0; trial < 300; ++trial) {
        const int M = 1 + trial % 5, N = 1 + (trial / 5) % 6;
        Eigen::MatrixXd c(M, N);
        for (int i = 0; i < M; ++i)
            for (int j = 0; j < N; ++j) c(i, j) = u(gen);
        const double gate = trial % 3 == 0 ? std::numeric_limits<double>::infinity() : 9.21;
        const auto m = flowtrack::assign(c, gate);
        double tot = 0;
        std::vector<char> rows(M, 0), cols(N, 0);
        for (const auto& [i, j] : m) {
            ASSERT_LE(c(i, j), gate);
            ASSERT_FALSE(rows[i] || cols[j]);
            rows[i] = cols[j] = 1;
            tot += c(i, j);
        }
        const auto b = brute(c, gate);
        ASSERT_EQ(static_cast<int>(m.size()), b.first) << "trial " << trial;
        ASSERT_NEAR(tot, b.second, 1e-9) << "trial " << trial;
    }
    // the gate trap: solving ungated and dropping (1,1) afterwards would keep only one pair
    Eigen::MatrixXd trap(2, 2);
    trap << 0, 6, 6, 11;
    const auto m = flowtrack::assign(trap, 10.0);
    ASSERT_EQ(m.size(), 2u);
    EXPECT_EQ(m[0], std::make_pair(0, 1));
    EXPECT_EQ(m[1], std::make_pair(1, 0));
}

TEST(Eigen, GraphSceneFlowTwoPointsClosedForm) {
    // (0.01 I + 0.01 L) V = 0.1 (Y - X) with one unit edge: v = 1 +- 1/3
    Eigen::MatrixX3d X = Eigen::MatrixX3d::Zero(2, 3), Y = Eigen::MatrixX3d::Zero(2, 3);
    Y(0, 0) = 0.2;
    Eigen::SparseMatrix<double> W(2, 2);
    W.insert(0, 1) = 1.0;
    W.insert(1, 0) = 1.0;
    const Eigen::MatrixX3d V = flowtrack::graph_scene_flow(X, Y, 0.1, 0.01, W);
    EXPECT_NEAR(V(0, 0), 1 + 1.0 / 3, 1e-12);
    EXPECT_NEAR(V(1, 0), 1 - 1.0 / 3, 1e-12);
}

TEST(Eigen, GraphSceneFlowMatchesDenseSolve) {
    std::mt19937 gen(11);
    std::uniform_real_distribution<double> u(-0.1, 0.1);
    const int n = 40;
    Eigen::MatrixX3d X(n, 3), Y(n, 3);
    for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
            X(i, k) = u(gen);
            Y(i, k) = X(i, k) + 0.01 + 0.1 * u(gen);
        }
    const Eigen::SparseMatrix<double> W = flowtrack::knn_graph(X, 5, 0.05);
    const Eigen::MatrixXd Wd(W);
    EXPECT_LT((Wd - Wd.transpose()).cwiseAbs().maxCoeff(), 1e-15);
    for (int i = 0; i < n; ++i) {
        EXPECT_EQ(Wd(i, i), 0.0);
        EXPECT_GE((Wd.row(i).array() > 0).count(), 5);
    }
    const Eigen::MatrixXd L = Eigen::MatrixXd(Wd.rowwise().sum().asDiagonal()) - Wd;
    const double dt = 0.1, lam = 0.05;
    const Eigen::MatrixXd A = dt * dt * Eigen::MatrixXd::Identity(n, n) + lam * L;
    const Eigen::MatrixXd Vd = A.fullPivLu().solve(dt * (Y - X));
    EXPECT_LT((flowtrack::graph_scene_flow(X, Y, dt, lam, W) - Vd).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Eigen, VariationalLdltAndCgAgreeAndConstantFlowIsExact) {
    const int H = 7, W = 9;
    std::mt19937 gen(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    Eigen::MatrixXd a(H, W), b(H, W);
    for (int r = 0; r < H; ++r)
        for (int c = 0; c < W; ++c) {
            a(r, c) = u(gen);
            b(r, c) = a(r, c) + 0.02 * u(gen);
        }
    const auto v1 = flowtrack::variational_component(a, b, 0.1, 0.5, flowtrack::Solver::LDLT);
    const auto v2 = flowtrack::variational_component(a, b, 0.1, 0.5, flowtrack::Solver::CG);
    EXPECT_LT((v1 - v2).cwiseAbs().maxCoeff(), 1e-10);
    // b - a constant: the smoothness term vanishes, v = (b - a) / dt
    const auto v3 = flowtrack::variational_component(a, (a.array() + 0.03).matrix(), 0.1, 2.0);
    EXPECT_LT((v3.array() - 0.3).abs().maxCoeff(), 1e-12);
    // grid Laplacian: Neumann diagonal = neighbour count, rows sum to zero
    const Eigen::MatrixXd L(flowtrack::grid_laplacian(3, 4));
    EXPECT_EQ(L(0, 0), 2.0);
    EXPECT_EQ(L(1, 1), 3.0);
    EXPECT_EQ(L(5, 5), 4.0);
    EXPECT_LT(L.rowwise().sum().cwiseAbs().maxCoeff(), 1e-15);
}
