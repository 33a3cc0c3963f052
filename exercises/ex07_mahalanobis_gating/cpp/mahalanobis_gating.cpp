// Exercise mahalanobis_gating (C++): squared Mahalanobis distances and the chi-square gate.  See exercise.hpp.
#include "exercise.hpp"

Eigen::VectorXd mahalanobis_d2(const Eigen::VectorXd& z_pred, const Eigen::MatrixXd& S, const Eigen::MatrixXd& Z) {
    Eigen::VectorXd d2 = Eigen::VectorXd::Zero(Z.rows());
    // BEGIN SOLUTION
    const Eigen::LLT<Eigen::MatrixXd> llt(S);
    for (Eigen::Index j = 0; j < Z.rows(); ++j) {
        const Eigen::VectorXd r = Z.row(j).transpose() - z_pred;
        d2(j) = llt.matrixL().solve(r).squaredNorm();
    }
    // END SOLUTION
    return d2;
}

Eigen::VectorXi gate(const Eigen::VectorXd& d2, double threshold) {
    Eigen::VectorXi inside = Eigen::VectorXi::Zero(d2.size());
    // BEGIN SOLUTION
    for (Eigen::Index j = 0; j < d2.size(); ++j) inside(j) = d2(j) <= threshold ? 1 : 0;
    // END SOLUTION
    return inside;
}
