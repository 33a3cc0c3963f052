function [positions, P] = kalman_cv2d(measurements, dt, process_var, meas_var, x0, P0)
% KALMAN_CV2D  The syllabus' constant-velocity tracking script (section 11.1) as a function.
%
%   [positions, P] = kalman_cv2d(measurements, dt, process_var, meas_var)
%   [positions, P] = kalman_cv2d(measurements, dt, process_var, meas_var, x0, P0)
%
%   measurements : K x 2 measured positions [x y], one row per step
%   dt           : time step (> 0)
%   process_var  : acceleration variance q (>= 0)
%   meas_var     : measurement variance (> 0), R = meas_var * eye(2)
%   x0, P0       : initial state [px py vx vy]' (default zeros) and covariance (default 1e3*eye(4))
%   positions    : K x 2 estimated positions after each update
%   P            : 4 x 4 covariance after the last update
%
%   State [px; py; vx; vy]; predict x = F x, P = F P F' + Q; update with the Kalman gain.
  if nargin < 5 || isempty(x0), x0 = zeros(4, 1); end
  if nargin < 6 || isempty(P0), P0 = 1e3 * eye(4); end
  if ~isnumeric(measurements) || size(measurements, 2) ~= 2
    error('kalman_cv2d: measurements: expected a K x 2 matrix, got %s', mat2str(size(measurements)));
  end
  if ~(isscalar(dt) && dt > 0), error('kalman_cv2d: dt: expected a scalar > 0'); end
  if ~(isscalar(meas_var) && meas_var > 0), error('kalman_cv2d: meas_var: expected a scalar > 0'); end
  if numel(x0) ~= 4, error('kalman_cv2d: x0: expected 4 values'); end
  if ~isequal(size(P0), [4 4]), error('kalman_cv2d: P0: expected a 4 x 4 matrix'); end

  F = [1 0 dt 0;
       0 1 0  dt;
       0 0 1  0;
       0 0 0  1];
  H = [1 0 0 0;
       0 1 0 0];

  % FIX: the syllabus writes Q = q * blkdiag(Q1d, Q1d). For the state order [px py vx vy] that
  % correlates px with py (and vx with vy); the white-noise-acceleration model correlates each
  % position with its own velocity: Q = Q1d (x) I2 = kron(Q1d, eye(2)).
  Q = white_noise_q(dt, process_var, 2);
  R = meas_var * eye(2);

  x = x0(:);
  P = P0;
  K_steps = size(measurements, 1);
  positions = zeros(K_steps, 2);
  for k = 1:K_steps
    % Prediction
    x = F * x;
    P = F * P * F.' + Q;

    % Update
    z = measurements(k, :).';
    y = z - H * x;
    S = H * P * H.' + R;
    K = P * H.' / S;
    x = x + K * y;
    P = (eye(4) - K * H) * P;

    positions(k, :) = x(1:2).';
  end
end
