// flowtrack C++ port (Eigen): the syllabus' section 9 filter with the process noise fixed, and the
// scene-flow and association steps of sections 2-4 and 7, checked against the Python reference's
// test vectors (../vectors/*.json) by harness_eigen.cpp.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <utility>
#include <vector>

namespace flowtrack {

// Process noise of the white-noise-acceleration model for state [p_1..p_d, v_1..v_d]:
//   Q = q * Q1d (x) I_d,   Q1d = [[dt^4/4, dt^3/2], [dt^3/2, dt^2]].
// (Q1d (x) I_d puts Q1d[a][b] on the (a*d + i, b*d + i) entries: position i with velocity i.)
Eigen::MatrixXd white_noise_q(double dt, double q, int dim);

// Constant-velocity Kalman filter in 2-D, state x = [px, py, vx, vy], measurement z = [px, py].
//
// The syllabus' version sets Q.block<2,2>(0,0) = Q.block<2,2>(2,2) = Q1d, i.e. blkdiag(Q1d, Q1d).
// That is the right matrix only for the axis-major order [px, vx, py, vy]; for [px, py, vx, vy] it
// correlates px with py (and vx with vy) and drops each axis' position-velocity covariance. The
// correct matrix for this state order is Q = q * Q1d (x) I2 (white_noise_q above).
struct KalmanFilterCV2D {
    double dt;
    Eigen::Matrix4d F;
    Eigen::Matrix<double, 2, 4> H;
    Eigen::Matrix4d Q;
    Eigen::Matrix2d R;
    Eigen::Vector4d x;
    Eigen::Matrix4d P;

    // The syllabus' constructor: x0 = 0, P0 = 1e3 I.
    KalmanFilterCV2D(double dt_, double process_var, double meas_var);
    // Any prior.
    KalmanFilterCV2D(double dt_, double process_var, double meas_var, const Eigen::Vector4d& x0,
                     const Eigen::Matrix4d& P0);

    void predict();
    // Joseph-form update (I-KH) P (I-KH)^T + K R K^T: keeps P symmetric positive semi-definite.
    void update(const Eigen::Vector2d& z);
    Eigen::Vector2d position() const { return x.head<2>(); }
};

// d pi / d X of the pinhole projection pi(X) = (fx X/Z + cx, fy Y/Z + cy), Z > 0.
Eigen::Matrix<double, 2, 3> projection_jacobian(const Eigen::Vector3d& X, double fx, double fy,
                                                double cx, double cy);

// Squared Mahalanobis distances cost(i, j) = (z_j - zp_i)^T S_i^{-1} (z_j - zp_i).
// z_pred (M, m), S: M matrices (m, m), Z (N, m).
Eigen::MatrixXd mahalanobis_cost(const Eigen::MatrixXd& z_pred, const std::vector<Eigen::MatrixXd>& S,
                                 const Eigen::MatrixXd& Z);

// Minimum-cost assignment of a rectangular cost matrix (Hungarian / Kuhn-Munkres, O(n^2 m)):
// row_to_col[i] = column of row i, or -1 (only when rows > cols).
std::vector<int> hungarian(const Eigen::MatrixXd& cost);

// Gated assignment: among the pairs with cost <= gate, a matching with the most pairs and, among
// those, the least total cost (admissible costs scaled into [0, 1], every other pair the
// prohibitive cost min(M, N) + 1, solved by hungarian(), prohibitive pairs dropped).
// Returns [track, detection] pairs sorted by track.
std::vector<std::pair<int, int>> assign(const Eigen::MatrixXd& cost, double gate);

// Symmetric kNN affinities: every point joined to its k nearest other points (brute force,
// Euclidean), union of the directed edges, w_ij = exp(-|X_i - X_j|^2 / sigma^2).
Eigen::SparseMatrix<double> knn_graph(const Eigen::MatrixX3d& points, int k, double sigma);

// Combinatorial Laplacian L = D - W.
Eigen::SparseMatrix<double> graph_laplacian(const Eigen::SparseMatrix<double>& W);

// Graph scene flow: solve (dt^2 I + lam L) V = dt (Y - X), one SimplicialLDLT factorisation for the
// three columns.
Eigen::MatrixX3d graph_scene_flow(const Eigen::MatrixX3d& X, const Eigen::MatrixX3d& Y, double dt,
                                  double lam, const Eigen::SparseMatrix<double>& W);

// Laplacian of the 4-neighbour grid graph on H x W pixels (5-point stencil, Neumann boundary),
// pixel (r, c) has index r * W + c.
Eigen::SparseMatrix<double> grid_laplacian(int H, int W);

enum class Solver { LDLT, CG };

// Variational scene flow, one component: (dt^2 I + lam L_grid) v = dt (b - a), a, b (H, W).
Eigen::MatrixXd variational_component(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double dt,
                                      double lam, Solver solver = Solver::LDLT);

}  // namespace flowtrack
