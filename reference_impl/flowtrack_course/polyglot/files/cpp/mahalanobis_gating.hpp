// mahalanobis_gating: squared Mahalanobis distances of detections to a predicted measurement, and the gate.
#pragma once
#include <Eigen/Dense>

// d2(j) = (Z.row(j)' - z_pred)' S^-1 (Z.row(j)' - z_pred); Z is N x m, S is m x m (positive definite).
Eigen::VectorXd mahalanobis_d2(const Eigen::VectorXd& z_pred, const Eigen::MatrixXd& S, const Eigen::MatrixXd& Z);

// inside(j) = 1 if d2(j) <= threshold, else 0.
Eigen::VectorXi gate(const Eigen::VectorXd& d2, double threshold);
