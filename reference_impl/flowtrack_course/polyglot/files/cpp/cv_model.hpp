// cv_model: the constant-velocity model of a 2-D point, state [px, py, vx, vy].
#pragma once
#include <Eigen/Dense>

// Fill F (the state transition over dt) and Q (the process noise: a white acceleration of variance q
// on each axis, constant over a step). On one axis, with the state [p, v], that noise is
// q * Q1d, Q1d = [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]: place its entries for the state order
// [px, py, vx, vy] (which entries of Q are the (px, vx) pair?).
void cv_model(double dt, double q, Eigen::Matrix4d& F, Eigen::Matrix4d& Q);
