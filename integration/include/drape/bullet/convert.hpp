// drape/bullet/convert.hpp: the conversions at the Bullet boundary. Bullet is single
// precision (btScalar), drape double precision: a btVector3 widens exactly, a Vec3 rounds to
// the nearest float. The one copy of them for drape::bullet and for the programs that use it.
#pragma once

#include "drape/mesh.hpp"

#include <Eigen/Core>
#include <LinearMath/btMatrix3x3.h>
#include <LinearMath/btVector3.h>

namespace drape::bullet {

/// A Bullet vector in double precision (exact).
inline Vec3 toVec(const btVector3& v) {
    return Vec3(double(v.x()), double(v.y()), double(v.z()));
}

/// A drape vector in Bullet's precision (rounded).
inline btVector3 toBt(const Vec3& v) {
    return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z()));
}

/// A Bullet matrix in double precision (exact).
inline Eigen::Matrix3d toMat(const btMatrix3x3& m) {
    Eigen::Matrix3d r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            r(i, j) = double(m[i][j]);
    return r;
}

} // namespace drape::bullet
