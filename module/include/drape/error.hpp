// drape/error.hpp: the one exception type drape throws, with a code saying what kind of
// problem it is. Messages name the offending field, particle, spring or triangle.
#pragma once

#include <stdexcept>
#include <string>

namespace drape {

/// What went wrong, for callers that want to react by kind rather than parse the message.
enum class ErrorCode {
    InvalidArgument, ///< a parameter is out of its valid range (negative mass, zero stiffness...)
    NonFinite,       ///< a NaN or infinity in an input or in the simulated state
    IndexOutOfRange, ///< a particle, vertex or triangle index beyond the array it indexes
    DegenerateTriangle, ///< a triangle with repeated vertices or (near) zero area
    InvalidMesh,        ///< a mesh that cannot be a cloth (no triangles, too large...)
    UnstableTimeStep,   ///< the time step is beyond the integrator's stability limit
    SimulationFailure,  ///< the state blew up during a step
    FileError, ///< a file could not be read or written, or holds what it cannot (drape::io)
};

/// Returns a short, stable name for an error code ("invalid argument", ...).
const char* toString(ErrorCode code) noexcept;

/// The exception thrown by every drape entry point on bad input or a failed step.
class Error : public std::runtime_error {
  public:
    Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
    /// The kind of problem.
    ErrorCode code() const noexcept { return code_; }

  private:
    ErrorCode code_;
};

} // namespace drape
