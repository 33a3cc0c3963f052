// flowtrack C++ port (PCL): the only translation unit that includes PCL's headers.
#include "flowtrack/rigid_icp.hpp"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>

#include <stdexcept>

namespace flowtrack {

namespace {
pcl::PointCloud<pcl::PointXYZ>::Ptr to_cloud(const Eigen::MatrixX3d& P) {
    pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
    cloud->resize(static_cast<size_t>(P.rows()));
    for (Eigen::Index i = 0; i < P.rows(); ++i)
        (*cloud)[i] = pcl::PointXYZ(static_cast<float>(P(i, 0)), static_cast<float>(P(i, 1)),
                                    static_cast<float>(P(i, 2)));
    return cloud;
}
}  // namespace

Eigen::Matrix4d rigid_icp_pcl(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target, double threshold,
                              int max_iter) {
    if (source.rows() < 3 || target.rows() < 3) throw std::invalid_argument("clouds need >= 3 points");
    if (!(threshold > 0)) throw std::invalid_argument("threshold must be > 0");
    if (max_iter < 1) throw std::invalid_argument("max_iter must be >= 1");
    // PCL works in float: centre both clouds on the source centroid so that coordinates stay small
    // (float's relative precision 6e-8 of ~1 m would otherwise cost ~1e-7 m), then undo the shift.
    const Eigen::RowVector3d c = source.colwise().mean();
    const Eigen::MatrixX3d src = source.rowwise() - c, dst = target.rowwise() - c;
    pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> icp;
    icp.setInputSource(to_cloud(src));
    icp.setInputTarget(to_cloud(dst));
    icp.setMaxCorrespondenceDistance(threshold);
    icp.setMaximumIterations(max_iter);
    icp.setTransformationEpsilon(1e-12);
    icp.setTransformationRotationEpsilon(1.0 - 1e-12);
    icp.setEuclideanFitnessEpsilon(1e-12);
    // iterate to the fixed point like the reference (open3d with relative criteria 1e-12), not to
    // PCL's default 1e-5 relative change of the mean squared error
    icp.getConvergeCriteria()->setRelativeMSE(1e-12);
    pcl::PointCloud<pcl::PointXYZ> aligned;
    icp.align(aligned);
    if (!icp.hasConverged()) throw std::runtime_error("pcl ICP did not converge");
    const Eigen::Matrix4d Tc = icp.getFinalTransformation().cast<double>();
    // T x = Tc (x - c) + c
    Eigen::Matrix4d shift = Eigen::Matrix4d::Identity(), unshift = Eigen::Matrix4d::Identity();
    shift.block<3, 1>(0, 3) = -c.transpose();
    unshift.block<3, 1>(0, 3) = c.transpose();
    return unshift * Tc * shift;
}

Eigen::MatrixX3d rigid_flow(const Eigen::Matrix4d& T, const Eigen::MatrixX3d& points, double dt) {
    if (!(dt > 0)) throw std::invalid_argument("dt must be > 0");
    const Eigen::MatrixX3d moved = (points * T.block<3, 3>(0, 0).transpose()).rowwise() +
                                   T.block<3, 1>(0, 3).transpose();
    return (moved - points) / dt;
}

}  // namespace flowtrack
