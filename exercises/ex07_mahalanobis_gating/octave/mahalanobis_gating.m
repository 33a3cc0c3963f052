function [d2, inside] = mahalanobis_gating(z_pred, S, Z, gate)
  % MAHALANOBIS_GATING  Squared Mahalanobis distances of the detections (rows of Z, N x m) to the
  %   predicted measurement z_pred (m x 1) with innovation covariance S (m x m), and the gate:
  %   d2(j) = (Z(j,:)' - z_pred)' inv(S) (Z(j,:)' - z_pred),  inside(j) = d2(j) <= gate (1 or 0).
  d2 = zeros(size(Z, 1), 1);
  inside = zeros(size(Z, 1), 1);
  % BEGIN SOLUTION
  L = chol(S, 'lower');
  r = L \ (Z' - z_pred);
  d2 = sum(r .^ 2, 1)';
  inside = double(d2 <= gate);
  % END SOLUTION
end
