// flowtrack C++ port (Eigen): implementations. See include/flowtrack/flowtrack.hpp.
#include "flowtrack/flowtrack.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <unsupported/Eigen/KroneckerProduct>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

namespace flowtrack {

namespace {
void require(bool ok, const std::string& message) {
    if (!ok) throw std::invalid_argument(message);
}
}  // namespace

Eigen::MatrixXd white_noise_q(double dt, double q, int dim) {
    require(dt > 0, "dt must be > 0");
    require(q >= 0, "q must be >= 0");
    require(dim >= 1 && dim <= 3, "dim must be 1, 2 or 3");
    const double dt2 = dt * dt, dt3 = dt2 * dt, dt4 = dt2 * dt2;
    Eigen::Matrix2d Q1d;
    Q1d << 0.25 * dt4, 0.5 * dt3,
           0.5 * dt3, dt2;
    Eigen::MatrixXd Q = Eigen::kroneckerProduct(q * Q1d, Eigen::MatrixXd::Identity(dim, dim));
    return Q;
}

KalmanFilterCV2D::KalmanFilterCV2D(double dt_, double process_var, double meas_var)
    : KalmanFilterCV2D(dt_, process_var, meas_var, Eigen::Vector4d::Zero(),
                       Eigen::Matrix4d::Identity() * 1e3) {}

KalmanFilterCV2D::KalmanFilterCV2D(double dt_, double process_var, double meas_var,
                                   const Eigen::Vector4d& x0, const Eigen::Matrix4d& P0)
    : dt(dt_), x(x0), P(P0) {
    require(meas_var > 0, "meas_var must be > 0");
    F.setIdentity();
    F(0, 2) = dt;
    F(1, 3) = dt;
    H.setZero();
    H(0, 0) = 1.0;
    H(1, 1) = 1.0;
    // Fixed: Q1d (x) I2, not the syllabus' blkdiag(Q1d, Q1d) (see the header).
    Q = white_noise_q(dt, process_var, 2);
    R = meas_var * Eigen::Matrix2d::Identity();
}

void KalmanFilterCV2D::predict() {
    x = F * x;
    P = F * P * F.transpose() + Q;
}

void KalmanFilterCV2D::update(const Eigen::Vector2d& z) {
    const Eigen::Vector2d y = z - H * x;
    const Eigen::Matrix2d S = H * P * H.transpose() + R;
    // K = P H^T S^{-1}, via a Cholesky solve instead of S.inverse()
    const Eigen::Matrix<double, 4, 2> K = S.llt().solve(H * P).transpose();
    x = x + K * y;
    const Eigen::Matrix4d IKH = Eigen::Matrix4d::Identity() - K * H;
    P = IKH * P * IKH.transpose() + K * R * K.transpose();
}

Eigen::Matrix<double, 2, 3> projection_jacobian(const Eigen::Vector3d& X, double fx, double fy,
                                                double /*cx*/, double /*cy*/) {
    require(X.z() > 0, "X must have Z > 0");
    const double iz = 1.0 / X.z();
    Eigen::Matrix<double, 2, 3> J;
    J << fx * iz, 0.0, -fx * X.x() * iz * iz,
         0.0, fy * iz, -fy * X.y() * iz * iz;
    return J;
}

Eigen::MatrixXd mahalanobis_cost(const Eigen::MatrixXd& z_pred, const std::vector<Eigen::MatrixXd>& S,
                                 const Eigen::MatrixXd& Z) {
    const Eigen::Index M = z_pred.rows(), m = z_pred.cols(), N = Z.rows();
    require(static_cast<Eigen::Index>(S.size()) == M, "S must hold one (m, m) matrix per track");
    require(N == 0 || Z.cols() == m, "detections must have m columns like z_pred");
    Eigen::MatrixXd cost(M, N);
    for (Eigen::Index i = 0; i < M; ++i) {
        require(S[i].rows() == m && S[i].cols() == m, "S[i] must be (m, m)");
        Eigen::LLT<Eigen::MatrixXd> llt(S[i]);
        require(llt.info() == Eigen::Success, "S[i] must be positive definite");
        // (z - zp)^T S^{-1} (z - zp) = |L^{-1} (z - zp)|^2
        Eigen::MatrixXd D = (Z.rowwise() - z_pred.row(i)).transpose();  // (m, N)
        llt.matrixL().solveInPlace(D);
        cost.row(i) = D.colwise().squaredNorm();
    }
    return cost;
}

std::vector<int> hungarian(const Eigen::MatrixXd& cost) {
    const int rows = static_cast<int>(cost.rows()), cols = static_cast<int>(cost.cols());
    if (rows == 0 || cols == 0) return std::vector<int>(rows, -1);
    if (rows > cols) {  // solve the transpose, then invert the assignment
        const std::vector<int> c2r = hungarian(cost.transpose());
        std::vector<int> r2c(rows, -1);
        for (int j = 0; j < cols; ++j) r2c[c2r[j]] = j;
        return r2c;
    }
    // Kuhn-Munkres with potentials (rows <= cols), 1-based with a virtual column 0.
    const double inf = std::numeric_limits<double>::infinity();
    const int n = rows, m = cols;
    std::vector<double> u(n + 1, 0.0), v(m + 1, 0.0);
    std::vector<int> p(m + 1, 0), way(m + 1, 0);
    for (int i = 1; i <= n; ++i) {
        p[0] = i;
        int j0 = 0;
        std::vector<double> minv(m + 1, inf);
        std::vector<char> used(m + 1, 0);
        do {
            used[j0] = 1;
            const int i0 = p[j0];
            double delta = inf;
            int j1 = 0;
            for (int j = 1; j <= m; ++j) {
                if (used[j]) continue;
                const double cur = cost(i0 - 1, j - 1) - u[i0] - v[j];
                if (cur < minv[j]) {
                    minv[j] = cur;
                    way[j] = j0;
                }
                if (minv[j] < delta) {
                    delta = minv[j];
                    j1 = j;
                }
            }
            for (int j = 0; j <= m; ++j) {
                if (used[j]) {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
        } while (p[j0] != 0);
        do {
            const int j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
        } while (j0 != 0);
    }
    std::vector<int> r2c(n, -1);
    for (int j = 1; j <= m; ++j)
        if (p[j] != 0) r2c[p[j] - 1] = j - 1;
    return r2c;
}

std::vector<std::pair<int, int>> assign(const Eigen::MatrixXd& cost, double gate) {
    require(!std::isnan(gate), "gate must not be NaN");
    const Eigen::Index M = cost.rows(), N = cost.cols();
    std::vector<std::pair<int, int>> matches;
    if (M == 0 || N == 0) return matches;
    const auto admissible = [&](Eigen::Index i, Eigen::Index j) {
        return std::isfinite(cost(i, j)) && cost(i, j) <= gate;
    };
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (Eigen::Index i = 0; i < M; ++i)
        for (Eigen::Index j = 0; j < N; ++j)
            if (admissible(i, j)) {
                lo = std::min(lo, cost(i, j));
                hi = std::max(hi, cost(i, j));
            }
    if (!(lo <= hi)) return matches;  // nothing admissible
    // Every matching's admissible total (scaled into [0, 1] per pair) is <= min(M, N) < big, so the
    // optimum has the most admissible pairs first, the least admissible cost second.
    const double span = hi - lo, big = static_cast<double>(std::min(M, N)) + 1.0;
    Eigen::MatrixXd c(M, N);
    for (Eigen::Index i = 0; i < M; ++i)
        for (Eigen::Index j = 0; j < N; ++j)
            c(i, j) = admissible(i, j) ? (span > 0 ? (cost(i, j) - lo) / span : 0.0) : big;
    const std::vector<int> r2c = hungarian(c);
    for (int i = 0; i < static_cast<int>(M); ++i)
        if (r2c[i] >= 0 && admissible(i, r2c[i])) matches.emplace_back(i, r2c[i]);
    return matches;
}

Eigen::SparseMatrix<double> knn_graph(const Eigen::MatrixX3d& points, int k, double sigma) {
    const Eigen::Index n = points.rows();
    require(k >= 1 && k < n, "k must satisfy 1 <= k < N");
    require(sigma > 0, "sigma must be > 0");
    std::vector<Eigen::Triplet<double>> trips;
    trips.reserve(static_cast<size_t>(2 * n * k));
    std::vector<double> dist(n);
    std::vector<int> others;
    others.reserve(n - 1);
    for (Eigen::Index i = 0; i < n; ++i) {
        for (Eigen::Index j = 0; j < n; ++j) dist[j] = (points.row(j) - points.row(i)).norm();
        // the k nearest other points (ties by index); never an edge to itself
        others.clear();
        for (Eigen::Index j = 0; j < n; ++j)
            if (j != i) others.push_back(static_cast<int>(j));
        std::partial_sort(others.begin(), others.begin() + k, others.end(), [&](int a, int b) {
            return dist[a] < dist[b] || (dist[a] == dist[b] && a < b);
        });
        for (int e = 0; e < k; ++e) {
            const int j = others[e];
            const double r = dist[j] / sigma;
            const double w = std::exp(-r * r);
            trips.emplace_back(static_cast<int>(i), j, w);
            trips.emplace_back(j, static_cast<int>(i), w);
        }
    }
    Eigen::SparseMatrix<double> W(n, n);
    // union of the directed edges: an edge found from both ends keeps one (the same) weight
    W.setFromTriplets(trips.begin(), trips.end(), [](double a, double b) { return std::max(a, b); });
    W.prune(0.0);
    return W;
}

Eigen::SparseMatrix<double> graph_laplacian(const Eigen::SparseMatrix<double>& W) {
    require(W.rows() == W.cols(), "W must be square");
    Eigen::SparseMatrix<double> L = -W;
    const Eigen::VectorXd deg = W * Eigen::VectorXd::Ones(W.cols());
    for (Eigen::Index i = 0; i < W.rows(); ++i) L.coeffRef(i, i) += deg(i);
    L.makeCompressed();
    return L;
}

Eigen::MatrixX3d graph_scene_flow(const Eigen::MatrixX3d& X, const Eigen::MatrixX3d& Y, double dt,
                                  double lam, const Eigen::SparseMatrix<double>& W) {
    const Eigen::Index n = X.rows();
    require(Y.rows() == n, "targets must have the shape of points");
    require(dt > 0, "dt must be > 0");
    require(lam >= 0, "lam must be >= 0");
    require(W.rows() == n && W.cols() == n, "W must be (N, N)");
    Eigen::SparseMatrix<double> I(n, n);
    I.setIdentity();
    const Eigen::SparseMatrix<double> A = dt * dt * I + lam * graph_laplacian(W);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
    if (ldlt.info() != Eigen::Success) throw std::runtime_error("graph_scene_flow: factorisation failed");
    const Eigen::MatrixX3d B = dt * (Y - X);
    return ldlt.solve(B);
}

Eigen::SparseMatrix<double> grid_laplacian(int H, int W) {
    require(H >= 1 && W >= 1, "grid must be at least 1 x 1");
    std::vector<Eigen::Triplet<double>> trips;
    const auto id = [W](int r, int c) { return r * W + c; };
    for (int r = 0; r < H; ++r)
        for (int c = 0; c < W; ++c) {
            // 4-neighbour edges to the right and below, each once
            if (c + 1 < W) {
                trips.emplace_back(id(r, c), id(r, c + 1), -1.0);
                trips.emplace_back(id(r, c + 1), id(r, c), -1.0);
                trips.emplace_back(id(r, c), id(r, c), 1.0);
                trips.emplace_back(id(r, c + 1), id(r, c + 1), 1.0);
            }
            if (r + 1 < H) {
                trips.emplace_back(id(r, c), id(r + 1, c), -1.0);
                trips.emplace_back(id(r + 1, c), id(r, c), -1.0);
                trips.emplace_back(id(r, c), id(r, c), 1.0);
                trips.emplace_back(id(r + 1, c), id(r + 1, c), 1.0);
            }
        }
    Eigen::SparseMatrix<double> L(H * W, H * W);
    L.setFromTriplets(trips.begin(), trips.end());  // duplicates summed: diagonal = degree
    return L;
}

Eigen::MatrixXd variational_component(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, double dt,
                                      double lam, Solver solver) {
    require(a.rows() == b.rows() && a.cols() == b.cols(), "a and b must have the same (H, W) shape");
    require(dt > 0, "dt must be > 0");
    require(lam >= 0, "lam must be >= 0");
    const int H = static_cast<int>(a.rows()), W = static_cast<int>(a.cols());
    const int n = H * W;
    Eigen::SparseMatrix<double> I(n, n);
    I.setIdentity();
    const Eigen::SparseMatrix<double> A = dt * dt * I + lam * grid_laplacian(H, W);
    Eigen::VectorXd rhs(n);
    for (int r = 0; r < H; ++r)
        for (int c = 0; c < W; ++c) rhs(r * W + c) = dt * (b(r, c) - a(r, c));
    Eigen::VectorXd v;
    if (solver == Solver::LDLT) {
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
        if (ldlt.info() != Eigen::Success) throw std::runtime_error("variational: factorisation failed");
        v = ldlt.solve(rhs);
    } else {
        Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg(A);
        cg.setTolerance(1e-14);
        cg.setMaxIterations(10 * n + 100);
        v = cg.solve(rhs);
        if (cg.info() != Eigen::Success) throw std::runtime_error("variational: CG did not converge");
    }
    Eigen::MatrixXd out(H, W);
    for (int r = 0; r < H; ++r)
        for (int c = 0; c < W; ++c) out(r, c) = v(r * W + c);
    return out;
}

}  // namespace flowtrack
