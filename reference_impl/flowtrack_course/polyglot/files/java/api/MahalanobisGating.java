// The signatures the harness calls (the grader compiles Harness.java against these; your file replaces them).
public final class MahalanobisGating {
    public static double[] d2(double[] zPred, double[][] S, double[][] Z) { throw new UnsupportedOperationException(); }
    public static int[] gate(double[] d2, double threshold) { throw new UnsupportedOperationException(); }
}
