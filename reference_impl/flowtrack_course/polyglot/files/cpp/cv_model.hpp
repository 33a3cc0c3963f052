// cv_model: the constant-velocity model of a 2-D point, state [px, py, vx, vy].
#pragma once
#include <Eigen/Dense>

// Fill F (state transition over dt) and Q (process noise of white acceleration with variance q,
// piecewise constant over a step: Q = q * kron(Q1d, I2), Q1d = [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]).
void cv_model(double dt, double q, Eigen::Matrix4d& F, Eigen::Matrix4d& Q);
