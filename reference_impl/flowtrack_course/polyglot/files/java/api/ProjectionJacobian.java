// The signatures the harness calls (the grader compiles Harness.java against these; your file replaces them).
public final class ProjectionJacobian {
    public static double[][] jacobian(double[] X, double fx, double fy, double cx, double cy) {
        throw new UnsupportedOperationException();
    }
}
