function Q = white_noise_q(dt, q, dim)
% WHITE_NOISE_Q  Discrete white-noise-acceleration covariance for the state [p_1..p_dim v_1..v_dim].
%
%   Q = white_noise_q(dt, q, dim) returns the (2 dim) x (2 dim) matrix Q1d (x) I_dim with
%   Q1d = q * [dt^4/4 dt^3/2; dt^3/2 dt^2].  (Not blkdiag(Q1d, ..., Q1d): that is the covariance
%   for the interleaved order [p_1 v_1 p_2 v_2 ...].)
  if nargin < 3, dim = 2; end
  if ~(isscalar(dt) && dt > 0), error('white_noise_q: dt: expected a scalar > 0'); end
  if ~(isscalar(q) && q >= 0), error('white_noise_q: q: expected a scalar >= 0'); end
  if ~(isscalar(dim) && dim >= 1 && dim == round(dim)), error('white_noise_q: dim: expected an integer >= 1'); end
  Q1d = q * [0.25 * dt^4, 0.5 * dt^3;
             0.5 * dt^3,  dt^2];
  Q = kron(Q1d, eye(dim));
end
