// Shared pieces of the sample games (see drape_samples/game.hpp).
#include "drape_samples/game.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace drape::samples {

FixedStepLoop::FixedStepLoop(double stepDt, double frameDt) : stepDt_(stepDt), frameDt_(frameDt) {
    if (!(std::isfinite(stepDt) && stepDt > 0.0 && std::isfinite(frameDt) && frameDt > 0.0))
        throw std::invalid_argument("FixedStepLoop: the step (" + std::to_string(stepDt) +
                                    " s) and the frame (" + std::to_string(frameDt) +
                                    " s) must be positive and finite");
}

std::filesystem::path framePath(const std::filesystem::path& folder, std::size_t index) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05zu.png", index);
    return folder / name;
}

} // namespace drape::samples
