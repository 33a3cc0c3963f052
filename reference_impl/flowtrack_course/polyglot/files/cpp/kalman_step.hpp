// kalman_step: one Kalman filter step (predict with F, Q; then update with the measurement z).
#pragma once
#include <Eigen/Dense>

// x (n), P (n x n) hold the estimate before the step and receive the estimate after it.
void kalman_step(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::MatrixXd& F, const Eigen::MatrixXd& Q,
                 const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, const Eigen::VectorXd& z);
