// drape/snapshot.hpp: saving and restoring a cloth's complete dynamic state, and a hash of
// it for determinism checks.
//
// A snapshot holds what a step reads: time, step count, positions, velocities, the cached
// forces, the aerodynamic forces the next opening kick takes (ClothState::aero), pins and
// their positions, the limiter's warm start, the sleep state, and the state
// each caller stage carries between steps (ClothStage::saveState; drape::bullet's contact
// stage keeps the rest of each particle's friction cone against dynamic bodies). User forces
// are not included (they are inputs the caller sets again), nor are grabs. Kinematic paths are
// functions and cannot be stored: a restored cloth keeps the kinematic paths it already has on
// particles the snapshot holds, and drops those on particles the snapshot frees (a drag in
// progress when the editor restored its snapshot went on moving a particle that reported
// itself free). A state stepped under a looser strain bound than the cloth's is brought
// within it as positions in the next step (ClothState::bound). Restoring into
// a cloth built from the same topology and settings (and, in a world, the same bodies in the
// same states) and then stepping gives bit-identical results to the uninterrupted run. The
// contact records of the cloth's ContactSet (drape::bullet's, of the step before) describe the
// state that was: restoring clears them, as in a cloth just added to its world (review 20: with
// them kept, each replay of a ball thrown into a curtain from one snapshot ended elsewhere).
// So a snapshot taken after an edit and before the next step (its forces not evaluated) replays
// without the records the uninterrupted run's first force evaluation read.
//
// File layout (little-endian): "DRAPESNP", u32 version (6; 2 to 5 are still read), u64 topology
// fingerprint, u64 particle count, f64 time, u64 steps, u8 forces-valid, then per particle
// x, v, f (9 f64) and u8 pinned, then per spring the limiter's warm start (f64). Version 3
// goes on with u8 asleep, f64 quiet time, u8 has-anchors and then per particle its sleep
// anchor (3 f64); version 4 then has u8 has-aerodynamics and per particle its carried
// aerodynamic force (3 f64); version 5 then has u8 over-bound (ClothState::overBound), and
// version 6 f64 the strain bound the state was stepped under (ClothState::bound); from version 3
// on, u32 stage count and per stage u32 name length, the name, u64 state length and the state.
// Last, a u64 FNV-1a checksum of everything before it. An older snapshot carries no
// aerodynamics (the next step evaluates them), no over-bound flag (false) and no bound (not
// known: its springs are checked against the cloth's bound).
#pragma once

#include "drape/cloth.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace drape {

/// FNV-1a 64-bit hash of the cloth's positions and velocities (bit patterns): equal hashes
/// mean (with overwhelming probability) bit-identical states.
std::uint64_t stateHash(const Cloth& cloth);

/// A fingerprint of the topology (rest positions, triangles): snapshots refuse to load into
/// a cloth with a different one.
std::uint64_t topologyFingerprint(const ClothTopology& topology);

/// Serialises the cloth's state to bytes / a file. Throws drape::Error on I/O failure.
std::vector<unsigned char> saveSnapshot(const Cloth& cloth);
void saveSnapshotFile(const Cloth& cloth, const std::string& path);

/// The largest snapshot file loadSnapshotFile reads (4 GiB: a cloth of kMaxParticles with
/// its sleep anchors and warm start fits) [bytes].
inline constexpr std::uint64_t kMaxSnapshotFileBytes = 4ull << 30;

/// Restores a state saved by saveSnapshot. Throws drape::Error (InvalidArgument) naming the
/// problem for a truncated, corrupt or foreign snapshot; the cloth is unchanged then.
void loadSnapshot(Cloth& cloth, const std::vector<unsigned char>& bytes);
/// loadSnapshot of a file's bytes. The path must name a regular file of at most
/// kMaxSnapshotFileBytes, as drape::io requires of mesh files: a folder, a FIFO or a device
/// (/dev/zero) is refused by name (drape::Error InvalidArgument) without blocking or reading.
void loadSnapshotFile(Cloth& cloth, const std::string& path);

} // namespace drape
