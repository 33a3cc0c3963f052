// projection_jacobian: d(u, v)/d(X, Y, Z) of the pinhole projection u = fx X/Z + cx, v = fy Y/Z + cy.
#pragma once
#include <Eigen/Dense>

Eigen::Matrix<double, 2, 3> projection_jacobian(const Eigen::Vector3d& X, double fx, double fy, double cx, double cy);
