function [x, P] = kalman_step(x, P, F, Q, H, R, z)
  % KALMAN_STEP  One Kalman filter step: predict with F, Q, then update with the measurement z.
  %   x (n x 1), P (n x n): the estimate before the step in, after the step out.
  % BEGIN SOLUTION
  x = F * x;
  P = F * P * F' + Q;
  S = H * P * H' + R;
  K = (S \ (H * P))';
  x = x + K * (z - H * x);
  I_KH = eye(numel(x)) - K * H;
  P = I_KH * P * I_KH' + K * R * K';
  % END SOLUTION
end
