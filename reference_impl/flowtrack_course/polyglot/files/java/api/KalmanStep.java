// The signatures the harness calls (the grader compiles Harness.java against these; your file replaces them).
public final class KalmanStep {
    public static void step(double[] x, double[][] P, double[][] F, double[][] Q, double[][] H, double[][] R,
            double[] z) { throw new UnsupportedOperationException(); }
}
