// validate.hpp (private to drape::bullet): checks of the settings and the arguments the
// handle is given, with messages that name the bad value.
#pragma once

#include "drape/bullet/settings.hpp"
#include "drape/error.hpp"

#include <string>

namespace drape::bullet::detail {

/// A number for an error message (6 significant digits).
std::string num(double v);

/// Throws drape::Error(code, message) unless ok.
inline void require(bool ok, ErrorCode code, const std::string& message) {
    if (!ok) throw Error(code, message);
}

/// Throws drape::Error (InvalidArgument) unless unitsPerMetre is in [kMinUnitsPerMetre,
/// kMaxUnitsPerMetre]; `who` prefixes the message.
void validateUnitsPerMetre(double unitsPerMetre, const std::string& who = "");

/// Throws drape::Error naming the first bad setting.
void validate(const BulletClothSettings& s);

} // namespace drape::bullet::detail
