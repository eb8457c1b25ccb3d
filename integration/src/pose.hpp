// pose.hpp (private to drape::bullet): a body's rigid transform in double precision.
#pragma once

#include "drape/bullet/convert.hpp"

#include <LinearMath/btTransform.h>

namespace drape::bullet::detail {

/// A rigid transform in double precision: world = R local + t.
struct Pose {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Vec3 t = Vec3::Zero();
    Vec3 toLocal(const Vec3& w) const { return R.transpose() * (w - t); }
    Vec3 toWorld(const Vec3& l) const { return R * l + t; }
    Pose operator*(const Pose& child) const { return Pose{R * child.R, R * child.t + t}; }
};

/// A Bullet transform in double precision (exact).
inline Pose toPose(const btTransform& t) {
    return Pose{toMat(t.getBasis()), toVec(t.getOrigin())};
}

} // namespace drape::bullet::detail
