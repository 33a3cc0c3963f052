// assignment: the linear assignment problem (give each track its own detection at the least total cost).
#pragma once
#include <vector>

#include <Eigen/Dense>

// C (n x m, n <= m): C(i, j) is the cost of giving row i (a track) column j (a detection).
// Returns a (n entries): row i gets column a[i]; the a[i] are distinct and sum_i C(i, a[i]) is the
// smallest possible. (Small n: trying every assignment is fine; the Hungarian algorithm is O(n^2 m).)
std::vector<int> assignment(const Eigen::MatrixXd& C);
