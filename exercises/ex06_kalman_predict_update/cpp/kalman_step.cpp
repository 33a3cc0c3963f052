// Exercise kalman_step (C++): one predict/update step of the Kalman filter.  See exercise.hpp.
#include "exercise.hpp"

void kalman_step(Eigen::VectorXd& x, Eigen::MatrixXd& P, const Eigen::MatrixXd& F, const Eigen::MatrixXd& Q,
                 const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, const Eigen::VectorXd& z) {
    // BEGIN SOLUTION
    x = F * x;
    P = F * P * F.transpose() + Q;
    const Eigen::MatrixXd S = H * P * H.transpose() + R;
    const Eigen::MatrixXd K = S.ldlt().solve(H * P).transpose();  // P H' S^-1 (S, P symmetric)
    x += K * (z - H * x);
    const Eigen::MatrixXd I_KH = Eigen::MatrixXd::Identity(x.size(), x.size()) - K * H;
    P = I_KH * P * I_KH.transpose() + K * R * K.transpose();  // Joseph form
    // END SOLUTION
}
