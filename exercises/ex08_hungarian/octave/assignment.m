function a = assignment(C)
  % ASSIGNMENT  The linear assignment problem: give each track its own detection at the least cost.
  %   C (n x m, n <= m): C(i, j) is the cost of giving row i (a track) column j (a detection).
  %   a (1 x n): row i gets column a(i) (1-based); the a(i) are distinct and sum of C(i, a(i)) is the
  %   smallest possible. Taking, row after row, the cheapest column still free is not enough: the
  %   cheapest column of the first row may be the only cheap one of the second. n is small here
  %   (n <= 6, m <= n + 2): trying every assignment is fine (nchoosek, perms), or write the Hungarian
  %   algorithm.
  [n, m] = size(C);
  a = ones(1, n);
  % BEGIN SOLUTION
  best = inf;
  subsets = nchoosek(1:m, n);  % which n columns are used ...
  P = perms(1:n);              % ... and in which order
  for s = 1:size(subsets, 1)
    cols = subsets(s, :);
    for p = 1:size(P, 1)
      cand = cols(P(p, :));
      cost = sum(C(sub2ind([n, m], 1:n, cand)));
      if cost < best
        best = cost;
        a = cand;
      end
    end
  end
  % END SOLUTION
end
