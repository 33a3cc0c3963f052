// The signatures the harness calls (the grader compiles Harness.java against these; your file replaces them).
public final class Assignment {
    public static int[] solve(double[][] C) { throw new UnsupportedOperationException(); }
}
