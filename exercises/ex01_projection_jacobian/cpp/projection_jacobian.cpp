// Exercise projection_jacobian (C++): the Jacobian of the pinhole projection.  See exercise.hpp.
#include "exercise.hpp"

Eigen::Matrix<double, 2, 3> projection_jacobian(const Eigen::Vector3d& X, double fx, double fy, double cx, double cy) {
    Eigen::Matrix<double, 2, 3> J = Eigen::Matrix<double, 2, 3>::Zero();
    // BEGIN SOLUTION
    (void)cx;
    (void)cy;
    const double iz = 1.0 / X(2);
    J(0, 0) = fx * iz;
    J(0, 2) = -fx * X(0) * iz * iz;
    J(1, 1) = fy * iz;
    J(1, 2) = -fy * X(1) * iz * iz;
    // END SOLUTION
    return J;
}
