// The signatures the harness calls (the grader compiles Harness.java against these; your file replaces them).
public final class CvModel {
    public static double[][] transition(double dt) { throw new UnsupportedOperationException(); }
    public static double[][] processNoise(double dt, double q) { throw new UnsupportedOperationException(); }
}
