// flowtrack C++ port (PCL): rigid scene flow by pcl::IterativeClosestPoint (syllabus section 9).
// Kept out of flowtrack.hpp so that only one translation unit pays for PCL's headers.
#pragma once

#include <Eigen/Dense>

namespace flowtrack {

// Point-to-point ICP from the identity aligning source to target (N x 3 and M x 3, metres); pairs
// farther apart than `threshold` are ignored. Returns the 4x4 rigid transform T (target ~ T source).
Eigen::Matrix4d rigid_icp_pcl(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target,
                              double threshold, int max_iter);

// Scene flow of the rigid motion: v_i = (T x_i - x_i) / dt.
Eigen::MatrixX3d rigid_flow(const Eigen::Matrix4d& T, const Eigen::MatrixX3d& points, double dt);

}  // namespace flowtrack
