// drape/stability.hpp: explicit-integrator time step limits.
//
// For a linear spring network, the largest angular frequency omega_max is the square root of
// the largest eigenvalue of M^-1 K. Each spring's 3x3 stiffness block
// k [n n^T + (1 - L0/l)(I - n n^T)] is bounded by k I while l >= L0 (and by k n n^T at rest),
// so the weighted graph Laplacian L (L_ii = sum_j k_ij, L_ij = -k_ij) with pinned rows removed
// gives an upper bound on omega_max^2 valid for any stretched state: lambda_max(M^-1 L).
// It is found by power iteration on the symmetric M^-1/2 L M^-1/2.
//   Velocity-Verlet, symplectic Euler (undamped):  dt < 2 / omega_max
//   classic RK4:                                   dt < 2.785 / omega_max (real-axis extent;
//                                                  2 sqrt(2) on the imaginary axis)
//   explicit Euler: unstable for any dt on an undamped spring (|1 + i omega dt| > 1), and
//                   needs dt < 2 / omega_max even with damping; we report 2 / omega_max
//   implicit Euler: unconditionally stable (no limit)
#pragma once

#include "drape/settings.hpp"
#include "drape/topology.hpp"

#include <vector>

namespace drape {

/// Upper bound on the largest angular frequency of the spring network [rad/s].
/// Particles with zero inverse mass are held fixed. Returns 0 when nothing can move.
double estimateMaxAngularFrequency(const ClothTopology& topology,
                                   const std::vector<double>& stiffness,
                                   const std::vector<double>& invMass, int iterations = 60);

/// Largest stable time step of `kind` for omega_max [s]; +infinity for implicit Euler or
/// omega_max = 0.
double stableTimeStep(IntegratorKind kind, double omegaMax);

/// Where the network is stiffest for its mass: each free particle's own bound on the
/// frequencies it takes part in, sqrt(sum_j k_ij (1/m_i + 1/sqrt(m_i m_j))) over its springs
/// (its row of the Gershgorin bound above). A particle far above the median is what sets the
/// stable step: a vertex only sliver triangles touch (it gets almost no mass) or two vertices
/// a hair apart that should be one (a very short, stiff spring).
struct LocalFrequency {
    Index particle = 0;       ///< the free particle with the highest bound
    double omega = 0.0;       ///< its bound [rad/s]
    double medianOmega = 0.0; ///< the median of the free particles' bounds [rad/s]
    double mass = 0.0;        ///< the particle's mass, 1 / its inverse mass [kg]
    double medianMass = 0.0;  ///< the median of the free particles' masses [kg]
};

/// Each particle's own bound (LocalFrequency) [rad/s], 0 for a fixed particle (zero inverse
/// mass). A particle far above the rest makes the cloth dear: the stable step scales as 1 /
/// omega_max, and pinning it (or welding or remeshing what makes it) gives the rest's
/// estimateMaxAngularFrequency.
std::vector<double> localAngularFrequencies(const ClothTopology& topology,
                                            const std::vector<double>& stiffness,
                                            const std::vector<double>& invMass);

/// The particle with the highest local bound (LocalFrequency); all zero when nothing can move.
LocalFrequency highestLocalFrequency(const ClothTopology& topology,
                                     const std::vector<double>& stiffness,
                                     const std::vector<double>& invMass);

} // namespace drape
