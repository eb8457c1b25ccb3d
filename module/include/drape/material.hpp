// drape/material.hpp: spring stiffness and particle masses from fabric properties.
//
// The paper ("Estimation of some key mechanics parameters") gives Young's modulus E and
// density rho for fabrics but its stiffness formula is missing from the text. We derive one
// by energy equivalence:
//
//   A thin isotropic membrane of thickness h stretched equibiaxially by a small strain eps
//   stores W = E h eps^2 / (1 - nu) per unit area. Give each edge e the stiffness
//
//       k_e = E h * sum_{t adjacent to e} A_t / |e|^2                                 (M1)
//
//   Stretching every edge by eps stores sum_e k_e (eps |e|)^2 / 2 = sum_t 3 E h A_t eps^2 / 2
//   (each triangle contributes through its three edges), i.e. W = 1.5 E h eps^2 per area,
//   which equals the membrane energy for nu = 1/3, the Poisson ratio a triangular spring
//   lattice has. (M1) holds for any triangle mesh, has units Pa * m = N/m, is linear in E and
//   h and is invariant under uniform refinement (a 2D spring network's stiffness does not
//   depend on spacing). On a square grid with diagonals it gives E h on the grid edges and
//   E h / 2 on the diagonals (interior edges).
//
// Masses: the area-lumped mass of particle i is rho h sum_{t contains i} A_t / 3 (each
// triangle's mass shared equally by its corners). For regular sheets the paper uses the
// uniform M / n of its eq. (6).
#pragma once

#include <optional>
#include <vector>

namespace drape {

class ClothTopology; // drape/topology.hpp

/// Physical fabric properties. The defaults are a medium woven cotton of 200 g/m^2.
struct FabricMaterial {
    /// E [Pa]; PET (Dacron) is about 1.2e10 Pa. Not given: ClothSettings chooses the
    /// stiffness (see ClothSettings::springStiffness, kAutomaticStretchWaveSpeed); a real
    /// fabric's E makes springs far too stiff for an explicit step at game rates, which the
    /// strain limiter stands in for.
    std::optional<double> youngsModulus;
    double thickness = 5e-4; ///< h [m]; woven fabrics are 1e-4 .. 1e-3 m
    /// rho [kg/m^3] (apparent density: mass per area over h); with the default h, 0.2 kg/m^2.
    double density = 400.0;
};

/// Stiffness of every spring by (M1) [N/m]. Throws if E or h is not positive and finite.
std::vector<double> springStiffnessFromMaterial(const ClothTopology& topology, double youngsModulus,
                                                double thickness);

/// Area-lumped particle masses rho h sum A_t / 3 [kg]. Throws on invalid rho or h.
std::vector<double> areaLumpedMasses(const ClothTopology& topology, double density,
                                     double thickness);

/// Uniform masses M / n as in the paper's eq. (6) [kg]. Throws if M is not positive.
std::vector<double> uniformMasses(const ClothTopology& topology, double totalMass);

} // namespace drape
