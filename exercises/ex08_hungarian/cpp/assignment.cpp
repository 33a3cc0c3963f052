// Exercise assignment (C++): the linear assignment problem.  See exercise.hpp.
//
// Give every row (track) its own column (detection) so that the total cost is the smallest. Taking,
// row after row, the cheapest column still free is not enough: the cheapest column of the first row
// may be the only cheap one of the second. Try every assignment (n is small), or write the Hungarian
// algorithm (potentials u, v with u_i + v_j <= C(i, j); augment along shortest paths).
#include "exercise.hpp"

#include <limits>

std::vector<int> assignment(const Eigen::MatrixXd& C) {
    const int n = static_cast<int>(C.rows()), m = static_cast<int>(C.cols());
    std::vector<int> a(n, 0);
    // BEGIN SOLUTION
    // Hungarian algorithm, rows added one at a time (1-based arrays; column 0 is a sentinel).
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> u(n + 1, 0.0), v(m + 1, 0.0);
    std::vector<int> row_of(m + 1, 0), way(m + 1, 0);
    for (int i = 1; i <= n; ++i) {
        row_of[0] = i;
        int j0 = 0;
        std::vector<double> minv(m + 1, inf);
        std::vector<bool> used(m + 1, false);
        do {  // Dijkstra-like search for the cheapest augmenting path from row i
            used[j0] = true;
            const int i0 = row_of[j0];
            double delta = inf;
            int j1 = 0;
            for (int j = 1; j <= m; ++j) {
                if (used[j]) continue;
                const double cur = C(i0 - 1, j - 1) - u[i0] - v[j];
                if (cur < minv[j]) {
                    minv[j] = cur;
                    way[j] = j0;
                }
                if (minv[j] < delta) {
                    delta = minv[j];
                    j1 = j;
                }
            }
            for (int j = 0; j <= m; ++j) {
                if (used[j]) {
                    u[row_of[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
        } while (row_of[j0] != 0);
        do {  // flip the path
            const int j1 = way[j0];
            row_of[j0] = row_of[j1];
            j0 = j1;
        } while (j0 != 0);
    }
    for (int j = 1; j <= m; ++j)
        if (row_of[j] != 0) a[row_of[j] - 1] = j - 1;
    // END SOLUTION
    return a;
}
