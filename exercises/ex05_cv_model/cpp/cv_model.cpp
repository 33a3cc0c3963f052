// Exercise cv_model (C++): the constant-velocity model, F and Q.  See exercise.hpp for the contract.
#include "exercise.hpp"

void cv_model(double dt, double q, Eigen::Matrix4d& F, Eigen::Matrix4d& Q) {
    // BEGIN SOLUTION
    F = Eigen::Matrix4d::Identity();
    F.topRightCorner<2, 2>() = dt * Eigen::Matrix2d::Identity();
    Eigen::Matrix2d q1;
    q1 << dt * dt * dt * dt / 4.0, dt * dt * dt / 2.0, dt * dt * dt / 2.0, dt * dt;
    for (int i = 0; i < 2; ++i)
        for (int k = 0; k < 2; ++k) Q.block<2, 2>(2 * i, 2 * k) = q * q1(i, k) * Eigen::Matrix2d::Identity();
    // END SOLUTION
}
