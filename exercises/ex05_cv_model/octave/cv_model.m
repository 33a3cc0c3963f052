function [F, Q] = cv_model(dt, q)
  % CV_MODEL  Constant-velocity model of a 2-D point, state [px; py; vx; vy].
  %   F (4x4) moves the state by dt; Q (4x4) is the noise of a white acceleration of variance q on
  %   each axis, constant over a step. On one axis, with the state [p; v], it is q * Q1d with
  %   Q1d = [dt^4/4, dt^3/2; dt^3/2, dt^2]: place its entries for the state order [px; py; vx; vy]
  %   (which entries of Q are the (px, vx) pair?).
  F = zeros(4);
  Q = zeros(4);
  % BEGIN SOLUTION
  F = [eye(2), dt * eye(2); zeros(2), eye(2)];
  Q = q * kron([dt^4 / 4, dt^3 / 2; dt^3 / 2, dt^2], eye(2));
  % END SOLUTION
end
