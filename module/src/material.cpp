// Stiffness (M1) and masses from fabric properties; the derivation is in material.hpp.
#include "drape/material.hpp"

#include "drape/error.hpp"
#include "drape/topology.hpp"

#include <cmath>
#include <string>
#include <unordered_map>

namespace drape {
namespace {

void requirePositive(double value, const char* name) {
    if (!std::isfinite(value)) {
        throw Error(ErrorCode::NonFinite, std::string(name) + " is not finite");
    }
    if (!(value > 0.0)) {
        throw Error(ErrorCode::InvalidArgument,
                    std::string(name) + " must be positive, got " + std::to_string(value));
    }
}

} // namespace

std::vector<double> springStiffnessFromMaterial(const ClothTopology& topology, double youngsModulus,
                                                double thickness) {
    requirePositive(youngsModulus, "material.youngsModulus");
    requirePositive(thickness, "material.thickness");
    const auto& springs = topology.springs();
    // Map each triangle edge to its spring through the adjacency of the smaller particle.
    const auto& off = topology.adjacencyOffsets();
    const auto& nbr = topology.adjacentParticles();
    const auto& spr = topology.adjacentSprings();
    auto springOf = [&](Index a, Index b) {
        for (Index k = off[a]; k < off[a + 1]; ++k) {
            if (nbr[k] == b) return spr[k];
        }
        return Index(-1); // unreachable: every triangle edge is a spring
    };
    std::vector<double> areaSum(springs.size(), 0.0);
    const auto& tris = topology.triangles();
    const auto& areas = topology.triangleRestAreas();
    for (std::size_t t = 0; t < tris.size(); ++t) {
        for (int c = 0; c < 3; ++c) {
            areaSum[springOf(tris[t][c], tris[t][(c + 1) % 3])] += areas[t];
        }
    }
    std::vector<double> k(springs.size());
    const double eh = youngsModulus * thickness;
    for (std::size_t s = 0; s < springs.size(); ++s) {
        const double l0 = springs[s].restLength;
        k[s] = eh * areaSum[s] / (l0 * l0);
    }
    return k;
}

std::vector<double> areaLumpedMasses(const ClothTopology& topology, double density,
                                     double thickness) {
    requirePositive(density, "material.density");
    requirePositive(thickness, "material.thickness");
    std::vector<double> m(topology.particleCount(), 0.0);
    const auto& tris = topology.triangles();
    const auto& areas = topology.triangleRestAreas();
    const double rhoH = density * thickness;
    for (std::size_t t = 0; t < tris.size(); ++t) {
        const double share = rhoH * areas[t] / 3.0;
        for (int c = 0; c < 3; ++c)
            m[tris[t][c]] += share;
    }
    for (std::size_t i = 0; i < m.size(); ++i) {
        if (!(m[i] > 0.0)) {
            throw Error(ErrorCode::InvalidMesh,
                        "particle " + std::to_string(i) +
                            " belongs to no triangle and would have zero mass");
        }
    }
    return m;
}

std::vector<double> uniformMasses(const ClothTopology& topology, double totalMass) {
    requirePositive(totalMass, "totalMass");
    return std::vector<double>(topology.particleCount(),
                               totalMass / static_cast<double>(topology.particleCount()));
}

} // namespace drape
