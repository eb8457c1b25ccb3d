// Settings checks (see validate.hpp).
#include "validate.hpp"

#include "drape/cloth_pair.hpp"

#include <cmath>
#include <sstream>

namespace drape::bullet::detail {

std::string num(double v) {
    std::ostringstream s;
    s.precision(6);
    s << v;
    return s.str();
}

void validateUnitsPerMetre(double unitsPerMetre, const std::string& who) {
    require(unitsPerMetre >= kMinUnitsPerMetre && unitsPerMetre <= kMaxUnitsPerMetre,
            ErrorCode::InvalidArgument,
            who + "unitsPerMetre must be in [1e-6, 1e6] (100 for centimetres), got " +
                num(unitsPerMetre));
}

void validate(const BulletClothSettings& s) {
    validateUnitsPerMetre(s.unitsPerMetre);
    const auto& c = s.contact;
    // unitsPerMetre set with lengths and speeds left at their values in metres: a centimetre
    // world would keep a 0.1 mm contact thickness (0.01 units), and with only the thickness
    // set a teleport speed of 0.5 m/s (50 units/s: a character walking at 1.5 m/s "jumped"
    // every sub-step; review 16). inUnits converts them all, or the program sets each.
    if (s.unitsPerMetre != 1.0) {
        const BulletClothSettings metres;
        std::string left;
        int count = 0;
        auto check = [&left, &count](double value, double metreDefault, const char* name) {
            if (value != metreDefault) return;
            ++count;
            left += (left.empty() ? "" : ", ") + std::string(name) + " (" + num(value) + ")";
        };
        check(c.thickness, metres.contact.thickness, "contact.thickness");
        check(c.depenetrationSpeed, metres.contact.depenetrationSpeed,
              "contact.depenetrationSpeed");
        check(s.teleportSpeed, metres.teleportSpeed, "teleportSpeed");
        check(s.selfCollision.thickness, metres.selfCollision.thickness, "selfCollision.thickness");
        check(s.clothCollision.thickness, metres.clothCollision.thickness,
              "clothCollision.thickness");
        // One value equal to its metre default can be the program's choice in its own unit (a
        // 0.01-unit thickness: 0.1 mm in centimetres; a scene file that gives it); two or more
        // are settings left in metres.
        require(count < 2, ErrorCode::InvalidArgument,
                "unitsPerMetre is " + num(s.unitsPerMetre) + " but " + left +
                    " still have their defaults in metres: start from "
                    "BulletClothSettings::inUnits(" +
                    num(s.unitsPerMetre) +
                    "), which converts every length and speed, or set each in the world's "
                    "units");
    }
    require(std::isfinite(c.thickness) && c.thickness > 0.0, ErrorCode::InvalidArgument,
            "contact.thickness must be positive and finite, got " + num(c.thickness));
    if (c.penaltyBand)
        require(std::isfinite(*c.penaltyBand) && *c.penaltyBand >= 0.0, ErrorCode::InvalidArgument,
                "contact.penaltyBand must be >= 0 and finite, got " + num(*c.penaltyBand));
    if (c.penaltyForce)
        require(std::isfinite(*c.penaltyForce) && *c.penaltyForce >= 0.0,
                ErrorCode::InvalidArgument,
                "contact.penaltyForce must be >= 0 and finite, got " + num(*c.penaltyForce));
    require(std::isfinite(c.frictionScale) && c.frictionScale >= 0.0, ErrorCode::InvalidArgument,
            "contact.frictionScale must be >= 0 and finite, got " + num(c.frictionScale));
    require(std::isfinite(c.depenetrationSpeed) && c.depenetrationSpeed > 0.0,
            ErrorCode::InvalidArgument,
            "contact.depenetrationSpeed must be positive and finite, got " +
                num(c.depenetrationSpeed));
    if (c.broadphaseMargin)
        require(std::isfinite(*c.broadphaseMargin) && *c.broadphaseMargin >= 0.0,
                ErrorCode::InvalidArgument,
                "contact.broadphaseMargin must be >= 0 and finite, got " +
                    num(*c.broadphaseMargin));
    if (s.substeps)
        require(*s.substeps >= 1, ErrorCode::InvalidArgument,
                "substeps must be >= 1, got " + std::to_string(*s.substeps));
    if (s.timeStep)
        require(std::isfinite(*s.timeStep) && *s.timeStep > 0.0, ErrorCode::InvalidArgument,
                "timeStep must be positive and finite, got " + num(*s.timeStep));
    require(std::isfinite(s.teleportSpeed) && s.teleportSpeed >= 0.0, ErrorCode::InvalidArgument,
            "teleportSpeed must be >= 0 and finite (0: off), got " + num(s.teleportSpeed));
    require(s.teleportTurn >= 0.0 && s.teleportTurn <= 3.141592653589793,
            ErrorCode::InvalidArgument,
            "teleportTurn must be in [0, pi] radians (0: off), got " + num(s.teleportTurn));
    require(s.threads >= 1 && s.threads <= 1024, ErrorCode::InvalidArgument,
            "threads must be between 1 and 1024, got " + std::to_string(s.threads));
    // selfCollision is the cloth's own: Cloth::setSelfCollision validates it.
    validateClothPair(s.clothCollision, "clothCollision.");
}

} // namespace drape::bullet::detail
