package flowtrack.ports;

import com.google.gson.JsonArray;
import com.google.gson.JsonObject;
import org.opencv.core.Core;
import org.opencv.core.CvType;
import org.opencv.core.Mat;
import org.opencv.core.MatOfByte;
import org.opencv.core.MatOfFloat;
import org.opencv.core.MatOfPoint2f;
import org.opencv.core.Point;
import org.opencv.core.Size;
import org.opencv.core.TermCriteria;
import org.opencv.video.Video;

/**
 * Pyramidal Lucas–Kanade ({@code Video.calcOpticalFlowPyrLK}) on the rendered image pair of a
 * {@code lucas_kanade} vector case, checked against the flow the reference predicts from the
 * ground-truth scene flow. Needs the OpenCV JNI library on {@code java.library.path}.
 */
public final class LucasKanade {
    private static boolean loaded = false;

    private LucasKanade() {
    }

    private static synchronized void loadNative() {
        if (!loaded) {
            System.loadLibrary(Core.NATIVE_LIBRARY_NAME);
            loaded = true;
        }
    }

    /** A CV_8UC1 image from nested lists of ints in [0, 255]. */
    static Mat image(JsonArray rows) {
        int h = rows.size();
        int w = rows.get(0).getAsJsonArray().size();
        byte[] data = new byte[h * w];
        for (int r = 0; r < h; ++r) {
            JsonArray row = rows.get(r).getAsJsonArray();
            if (row.size() != w) {
                throw new IllegalArgumentException("image: row " + r + " has " + row.size() + " values, expected " + w);
            }
            for (int c = 0; c < w; ++c) {
                int v = row.get(c).getAsInt();
                if (v < 0 || v > 255) {
                    throw new IllegalArgumentException("image: value " + v + " outside [0, 255]");
                }
                data[r * w + c] = (byte) v;
            }
        }
        Mat m = new Mat(h, w, CvType.CV_8UC1);
        m.put(0, 0, data);
        return m;
    }

    /**
     * Tracks {@code points} from {@code image0} to {@code image1}; returns the flow (K x 2) and
     * sets {@code status[k]} to the tracker's status.
     */
    public static double[][] track(Mat img0, Mat img1, double[][] points, int win, int maxLevel,
                                   int iterations, double eps, byte[] status) {
        loadNative();
        Point[] p = new Point[points.length];
        for (int k = 0; k < p.length; ++k) {
            p[k] = new Point(points[k][0], points[k][1]);
        }
        MatOfPoint2f prev = new MatOfPoint2f(p);
        MatOfPoint2f next = new MatOfPoint2f();
        MatOfByte st = new MatOfByte();
        MatOfFloat err = new MatOfFloat();
        TermCriteria crit = new TermCriteria(TermCriteria.COUNT + TermCriteria.EPS, iterations, eps);
        Video.calcOpticalFlowPyrLK(img0, img1, prev, next, st, err, new Size(win, win), maxLevel, crit);
        Point[] q = next.toArray();
        byte[] s = st.toArray();
        double[][] flow = new double[p.length][];
        for (int k = 0; k < p.length; ++k) {
            flow[k] = new double[] {q[k].x - p[k].x, q[k].y - p[k].y};
            status[k] = s[k];
        }
        return flow;
    }

    static void check(JsonObject in, JsonObject exp, Vectors.Check chk) {
        loadNative();
        Mat img0 = image(in.getAsJsonArray("image0"));
        Mat img1 = image(in.getAsJsonArray("image1"));
        double[][] pts = Vectors.mat(in.get("points"));
        byte[] status = new byte[pts.length];
        double[][] flow = track(img0, img1, pts, in.get("win_size").getAsInt(), in.get("max_level").getAsInt(),
                in.get("iterations").getAsInt(), in.get("epsilon").getAsDouble(), status);
        chk.add("flow", flow, Vectors.mat(exp.get("flow")));
        for (int k = 0; k < status.length; ++k) {
            if (status[k] != 1) {
                chk.fail("point " + k + " lost by the tracker (status 0)");
                break;
            }
        }
    }
}
