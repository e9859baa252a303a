// Wall time of a step's stages (Box2D's b2Profile): one lap per stage, each lap added to
// the stage's slot, in seconds of a steady clock.
#pragma once

#include <chrono>

namespace tearables::detail {

class StageTimer {
public:
    StageTimer() : last_(Clock::now()) {}
    /// Adds the time since the last lap (or the construction) to `slot`, s, and starts the next lap.
    void lap(double& slot) {
        const Clock::time_point now = Clock::now();
        slot += std::chrono::duration<double>(now - last_).count();
        last_ = now;
    }

private:
    using Clock = std::chrono::steady_clock;
    Clock::time_point last_;
};

}  // namespace tearables::detail
