// spring.hpp (private to module/): the two formulas every spring loop of the core uses, once.
// Each layout (the spring list, the packed blocks, the family slots of a sheet, the limiter's
// adjacency) calls these, so that they compute the same values in the same order.
#pragma once

#include "drape/mesh.hpp"

namespace drape::detail {

/// Eq. (4): a spring of stiffness k [N/m] and rest length L0 [m] whose ends are d = x_b - x_a
/// apart, l = |d| [m], pulls end a by springForceScale(k, l, L0) d [N] and end b by the
/// opposite. Coincident ends (l = 0, so d = 0) get a zero force: the division is then by 1, a
/// select rather than a branch, which keeps the loops that call it vectorisable.
inline double springForceScale(double k, double l, double restLength) {
    return k * (l - restLength) / (l + static_cast<double>(l == 0.0));
}

/// (l / L0)^2 [-] of a spring whose ends are (dx, dy, dz) apart [m], from 1 / L0^2: the strain
/// ratio without a square root (the limiter compares it with (1 + strain bound)^2).
inline double squaredLengthRatio(double dx, double dy, double dz, double inverseSquaredRest) {
    return (dx * dx + dy * dy + dz * dz) * inverseSquaredRest;
}
inline double squaredLengthRatio(const Vec3& d, double inverseSquaredRest) {
    return squaredLengthRatio(d.x(), d.y(), d.z(), inverseSquaredRest);
}

} // namespace drape::detail
