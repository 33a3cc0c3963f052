package flowtrack.ports;

/**
 * The small dense-matrix helpers that the syllabus' {@code KalmanFilterCV2D} (section 10) calls but
 * leaves out ("would be implemented with straightforward loops"). Matrices are row-major
 * {@code double[rows][cols]}, vectors {@code double[n]}; every helper checks its shapes and throws
 * {@link IllegalArgumentException} naming the argument.
 */
public final class MatrixOps {
    private MatrixOps() {
    }

    private static void requireRect(double[][] a, String name) {
        if (a == null || a.length == 0 || a[0].length == 0) {
            throw new IllegalArgumentException(name + ": expected a non-empty matrix");
        }
        for (double[] row : a) {
            if (row.length != a[0].length) {
                throw new IllegalArgumentException(name + ": rows of different lengths");
            }
        }
    }

    /** Sets every entry of {@code a} to zero. */
    public static void zeroMatrix(double[][] a) {
        for (double[] row : a) {
            java.util.Arrays.fill(row, 0.0);
        }
    }

    /** Overwrites the square matrix {@code a} with {@code scale * I}. */
    public static void identityMatrix(double[][] a, double scale) {
        requireRect(a, "a");
        if (a.length != a[0].length) {
            throw new IllegalArgumentException("a: expected a square matrix, got " + a.length + "x" + a[0].length);
        }
        zeroMatrix(a);
        for (int i = 0; i < a.length; ++i) {
            a[i][i] = scale;
        }
    }

    /** A new {@code n x n} matrix {@code scale * I}. */
    public static double[][] identityMatrix(int n, double scale) {
        if (n <= 0) {
            throw new IllegalArgumentException("n: expected n > 0, got " + n);
        }
        double[][] a = new double[n][n];
        identityMatrix(a, scale);
        return a;
    }

    /** {@code dst[r0 + i][c0 + j] += scale * block[i][j]}. */
    public static void addBlock(double[][] dst, double[][] block, int r0, int c0, double scale) {
        requireRect(block, "block");
        if (r0 < 0 || c0 < 0 || r0 + block.length > dst.length || c0 + block[0].length > dst[0].length) {
            throw new IllegalArgumentException("block: a " + block.length + "x" + block[0].length
                    + " block at (" + r0 + ", " + c0 + ") does not fit into " + dst.length + "x" + dst[0].length);
        }
        for (int i = 0; i < block.length; ++i) {
            for (int j = 0; j < block[0].length; ++j) {
                dst[r0 + i][c0 + j] += scale * block[i][j];
            }
        }
    }

    /** Kronecker product {@code a ⊗ b}: block (i, j) is {@code a[i][j] * b}. */
    public static double[][] kron(double[][] a, double[][] b) {
        requireRect(a, "a");
        requireRect(b, "b");
        int m = b.length;
        int n = b[0].length;
        double[][] c = new double[a.length * m][a[0].length * n];
        for (int i = 0; i < a.length; ++i) {
            for (int j = 0; j < a[0].length; ++j) {
                addBlock(c, b, i * m, j * n, a[i][j]);
            }
        }
        return c;
    }

    /** Matrix product {@code a b}, (m x k)(k x n) -> (m x n). */
    public static double[][] matMul(double[][] a, double[][] b) {
        requireRect(a, "a");
        requireRect(b, "b");
        if (a[0].length != b.length) {
            throw new IllegalArgumentException("b: expected " + a[0].length + " rows to multiply a "
                    + a.length + "x" + a[0].length + " matrix, got " + b.length);
        }
        double[][] c = new double[a.length][b[0].length];
        for (int i = 0; i < a.length; ++i) {
            for (int k = 0; k < b.length; ++k) {
                double aik = a[i][k];
                for (int j = 0; j < b[0].length; ++j) {
                    c[i][j] += aik * b[k][j];
                }
            }
        }
        return c;
    }

    /** Matrix-vector product {@code a x}, (m x n)(n) -> (m). */
    public static double[] matMul(double[][] a, double[] x) {
        requireRect(a, "a");
        if (a[0].length != x.length) {
            throw new IllegalArgumentException("x: expected length " + a[0].length + ", got " + x.length);
        }
        double[] y = new double[a.length];
        for (int i = 0; i < a.length; ++i) {
            double s = 0.0;
            for (int j = 0; j < x.length; ++j) {
                s += a[i][j] * x[j];
            }
            y[i] = s;
        }
        return y;
    }

    /** Transpose (m x n) -> (n x m). */
    public static double[][] transpose(double[][] a) {
        requireRect(a, "a");
        double[][] t = new double[a[0].length][a.length];
        for (int i = 0; i < a.length; ++i) {
            for (int j = 0; j < a[0].length; ++j) {
                t[j][i] = a[i][j];
            }
        }
        return t;
    }

    private static void sameShape(double[][] a, double[][] b) {
        requireRect(a, "a");
        requireRect(b, "b");
        if (a.length != b.length || a[0].length != b[0].length) {
            throw new IllegalArgumentException("b: expected shape " + a.length + "x" + a[0].length
                    + ", got " + b.length + "x" + b[0].length);
        }
    }

    /** {@code a + b}. */
    public static double[][] matAdd(double[][] a, double[][] b) {
        sameShape(a, b);
        double[][] c = new double[a.length][a[0].length];
        for (int i = 0; i < a.length; ++i) {
            for (int j = 0; j < a[0].length; ++j) {
                c[i][j] = a[i][j] + b[i][j];
            }
        }
        return c;
    }

    /** {@code a - b}. */
    public static double[][] matSub(double[][] a, double[][] b) {
        sameShape(a, b);
        double[][] c = new double[a.length][a[0].length];
        for (int i = 0; i < a.length; ++i) {
            for (int j = 0; j < a[0].length; ++j) {
                c[i][j] = a[i][j] - b[i][j];
            }
        }
        return c;
    }

    /** {@code a - b} for vectors. */
    public static double[] matSub(double[] a, double[] b) {
        if (a.length != b.length) {
            throw new IllegalArgumentException("b: expected length " + a.length + ", got " + b.length);
        }
        double[] c = new double[a.length];
        for (int i = 0; i < a.length; ++i) {
            c[i] = a[i] - b[i];
        }
        return c;
    }

    /**
     * Inverse of a 2x2 matrix by the adjugate, {@code [[d, -b], [-c, a]] / (ad - bc)}; throws when
     * the determinant is zero or not finite.
     */
    public static double[][] matInv2x2(double[][] s) {
        requireRect(s, "S");
        if (s.length != 2 || s[0].length != 2) {
            throw new IllegalArgumentException("S: expected a 2x2 matrix, got " + s.length + "x" + s[0].length);
        }
        double det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        if (det == 0.0 || !Double.isFinite(det)) {
            throw new IllegalArgumentException("S: singular 2x2 matrix (det = " + det + ")");
        }
        return new double[][] {{s[1][1] / det, -s[0][1] / det}, {-s[1][0] / det, s[0][0] / det}};
    }

    /** Copies {@code src} into {@code dst} (same shape). */
    public static void copyMatrix(double[][] src, double[][] dst) {
        sameShape(src, dst);
        for (int i = 0; i < src.length; ++i) {
            System.arraycopy(src[i], 0, dst[i], 0, src[i].length);
        }
    }
}
