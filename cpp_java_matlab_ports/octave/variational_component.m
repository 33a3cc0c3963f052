function v = variational_component(a, b, dt, lam)
% VARIATIONAL_COMPONENT  One component of quadratic variational scene flow on an H x W grid.
%
%   v = variational_component(a, b, dt, lam) minimises
%       sum_p (a(p) + v(p) dt - b(p))^2 + lam sum_{(p,q) 4-neighbours} (v(p) - v(q))^2,
%   i.e. solves the sparse system (dt^2 I + lam L) v = dt (b - a), L the Laplacian of the
%   4-neighbour grid graph (5-point stencil with Neumann boundary: a pixel's diagonal entry is its
%   number of neighbours). a, b: H x W; v: H x W.
  if ~isequal(size(a), size(b)) || ndims(a) ~= 2
    error('variational_component: b: expected the H x W shape of a');
  end
  if ~(isscalar(dt) && dt > 0), error('variational_component: dt: expected a scalar > 0'); end
  if ~(isscalar(lam) && lam >= 0), error('variational_component: lam: expected a scalar >= 0'); end
  [H, W] = size(a);
  L = kron(speye(W), path_laplacian(H)) + kron(path_laplacian(W), speye(H));  % column-major a(:)
  A = dt^2 * speye(H * W) + lam * L;
  v = reshape(A \ (dt * (b(:) - a(:))), H, W);
end

function D = path_laplacian(n)
  % Laplacian of the path graph on n nodes: tridiag(-1, 2, -1) with 1 at both ends.
  e = ones(n, 1);
  D = spdiags([-e, 2 * e, -e], -1:1, n, n);
  D(1, 1) = 1;
  D(n, n) = 1;
  if n == 1, D = sparse(0); end
end
