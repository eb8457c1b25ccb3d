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

/// The pose as a Bullet transform (rounded to btScalar).
inline btTransform toBtTransform(const Pose& p) {
    const Eigen::Matrix3d& R = p.R;
    const btMatrix3x3 basis(btScalar(R(0, 0)), btScalar(R(0, 1)), btScalar(R(0, 2)),
                            btScalar(R(1, 0)), btScalar(R(1, 1)), btScalar(R(1, 2)),
                            btScalar(R(2, 0)), btScalar(R(2, 1)), btScalar(R(2, 2)));
    return btTransform(basis, toBt(p.t));
}

/// The pose a body moving at linear velocity v and angular velocity w [rad/s] had `back`
/// seconds before `end` (its centre of mass at end.t).
inline Pose poseBefore(const Pose& end, const Vec3& v, const Vec3& w, double back) {
    Pose p = end;
    p.t = end.t - back * v;
    const double angle = w.norm() * back;
    if (angle > 0.0) p.R = Eigen::AngleAxisd(-angle, w.normalized()).toRotationMatrix() * end.R;
    return p;
}

/// Where a kinematic body is after a Bullet sub-step of dt [s] that starts at `from`, given
/// Bullet's pose `to` and velocities v, w. Bullet puts a kinematic body at its motion state's
/// pose in every internal sub-step of a stepSimulation call, with the velocity of the whole
/// call's motion (btRigidBody::saveKinematicState): at 30 fps, or after a hitch, the body
/// would make the frame's motion in its first sub-step. When the way from `from` to `to` is m
/// > 1 sub-steps of that velocity (translation and turn alike), the body is taken one
/// sub-step along it; otherwise (the last sub-step, or a pose set without that velocity: a
/// teleport) it is at `to`.
inline Pose followKinematic(const Pose& from, const Pose& to, const Vec3& v, const Vec3& w,
                            double dt) {
    const Vec3 d = to.t - from.t;
    const Eigen::AngleAxisd turn(Eigen::Matrix3d(to.R * from.R.transpose()));
    const double lin = v.norm() * dt, ang = w.norm() * dt;
    double m = 0.0;
    if (lin > 0.0)
        m = d.norm() / lin;
    else if (ang > 0.0)
        m = turn.angle() / ang;
    if (!(m > 1.0 + 1e-6) || !(m < 1e6)) return to;
    // The way is m steps of the velocity (Bullet's float velocities: a relative 1e-4).
    if ((d - m * dt * v).norm() > 1e-4 * d.norm() + 1e-9) return to;
    if (ang > 0.0 || turn.angle() > 1e-6) {
        if (!(ang > 0.0) || std::abs(turn.angle() - m * ang) > 1e-4 * turn.angle() + 1e-6 ||
            turn.axis().dot(w / w.norm()) < 1.0 - 1e-6)
            return to;
    }
    return poseBefore(from, -v, -w, dt); // dt after `from`, at v and w
}

/// A body's way from pose `from` to pose `to` within a step: the origin on the straight line,
/// the rotation about the fixed axis of to.R from.R^T (the shorter way), both at constant rates.
struct PosePath {
    PosePath(const Pose& start, const Pose& end)
        : from(start), shift(end.t - start.t), turn(Eigen::Matrix3d(end.R * start.R.transpose())) {}
    Pose from;
    Vec3 shift;             ///< to.t - from.t [m]
    Eigen::AngleAxisd turn; ///< to.R from.R^T, angle in [0, pi]
    /// The pose a fraction s in [0, 1] of the way.
    Pose at(double s) const {
        Pose p;
        p.t = from.t + s * shift;
        p.R = turn.angle() > 0.0
                  ? Eigen::Matrix3d(Eigen::AngleAxisd(s * turn.angle(), turn.axis()) * from.R)
                  : from.R;
        return p;
    }
};

} // namespace drape::bullet::detail
