/**
 * Exercise assignment (Java): the linear assignment problem. Plain arrays, row-major.
 *
 * <p>Give every row (track) its own column (detection) so that the total cost is the smallest.
 * Taking, row after row, the cheapest column still free is not enough: the cheapest column of the
 * first row may be the only cheap one of the second. Try every assignment (n is small), or write the
 * Hungarian algorithm (potentials u, v with u_i + v_j <= C[i][j]; augment along shortest paths).
 */
public final class Assignment {
    private Assignment() {}

    /**
     * C is n x m with n <= m: C[i][j] is the cost of giving row i column j. Returns a (n entries): row
     * i gets column a[i] (counted from 0); the a[i] are distinct and the sum of C[i][a[i]] is the
     * smallest possible.
     */
    public static int[] solve(double[][] C) {
        int n = C.length, m = n == 0 ? 0 : C[0].length;
        int[] a = new int[n];
        // BEGIN SOLUTION
        // Hungarian algorithm, rows added one at a time (1-based arrays; column 0 is a sentinel).
        double[] u = new double[n + 1], v = new double[m + 1];
        int[] rowOf = new int[m + 1], way = new int[m + 1];
        for (int i = 1; i <= n; i++) {
            rowOf[0] = i;
            int j0 = 0;
            double[] minv = new double[m + 1];
            java.util.Arrays.fill(minv, Double.POSITIVE_INFINITY);
            boolean[] used = new boolean[m + 1];
            do {  // Dijkstra-like search for the cheapest augmenting path from row i
                used[j0] = true;
                int i0 = rowOf[j0], j1 = 0;
                double delta = Double.POSITIVE_INFINITY;
                for (int j = 1; j <= m; j++) {
                    if (used[j]) continue;
                    double cur = C[i0 - 1][j - 1] - u[i0] - v[j];
                    if (cur < minv[j]) {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if (minv[j] < delta) {
                        delta = minv[j];
                        j1 = j;
                    }
                }
                for (int j = 0; j <= m; j++) {
                    if (used[j]) {
                        u[rowOf[j]] += delta;
                        v[j] -= delta;
                    } else {
                        minv[j] -= delta;
                    }
                }
                j0 = j1;
            } while (rowOf[j0] != 0);
            do {  // flip the path
                int j1 = way[j0];
                rowOf[j0] = rowOf[j1];
                j0 = j1;
            } while (j0 != 0);
        }
        for (int j = 1; j <= m; j++)
            if (rowOf[j] != 0) a[rowOf[j] - 1] = j - 1;
        // END SOLUTION
        return a;
    }
}
