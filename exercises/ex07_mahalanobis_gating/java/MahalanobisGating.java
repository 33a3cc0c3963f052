/**
 * Exercise mahalanobis_gating (Java): squared Mahalanobis distances of detections to a predicted
 * measurement, and the chi-square gate. Plain arrays, row-major.
 */
public final class MahalanobisGating {
    private MahalanobisGating() {}

    /** d2[j] = (Z[j] - zPred)' S^-1 (Z[j] - zPred); Z is N x m, S m x m positive definite. */
    public static double[] d2(double[] zPred, double[][] S, double[][] Z) {
        double[] d2 = new double[Z.length];
        // BEGIN SOLUTION
        int m = zPred.length;
        double[][] L = new double[m][m];  // Cholesky factor, S = L L'
        for (int i = 0; i < m; i++)
            for (int j = 0; j <= i; j++) {
                double s = S[i][j];
                for (int k = 0; k < j; k++) s -= L[i][k] * L[j][k];
                L[i][j] = i == j ? Math.sqrt(s) : s / L[j][j];
            }
        for (int n = 0; n < Z.length; n++) {
            double[] y = new double[m];  // solve L y = r
            for (int i = 0; i < m; i++) {
                double s = Z[n][i] - zPred[i];
                for (int k = 0; k < i; k++) s -= L[i][k] * y[k];
                y[i] = s / L[i][i];
                d2[n] += y[i] * y[i];
            }
        }
        // END SOLUTION
        return d2;
    }

    /** inside[j] = 1 if d2[j] <= threshold, else 0. */
    public static int[] gate(double[] d2, double threshold) {
        int[] inside = new int[d2.length];
        // BEGIN SOLUTION
        for (int j = 0; j < d2.length; j++) inside[j] = d2[j] <= threshold ? 1 : 0;
        // END SOLUTION
        return inside;
    }
}
