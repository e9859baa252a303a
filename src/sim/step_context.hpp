// The context of one step, shared by every material's stages.
#pragma once

#include "tearables/world.hpp"

#include <cstdint>

namespace tearables::detail {

class ThreadPool;
class IslandSolve;

/// Per-step context rebuilt each step (Box2D's b2StepContext).
struct StepContext {
    double h = 0.0;       ///< step, s
    double inv_h = 0.0;   ///< 1/h
    Vec3 gravity = Vec3::Zero();
    const WorldSettings* settings = nullptr;
    double time = 0.0;           ///< simulated time at the end of this step
    std::int64_t step = 0;       ///< number of this step
    /// Where a stage may split one big string's work (may be null: serial). Its forEach
    /// runs serially when nested in another, so stages called from a forEach over many
    /// strings stay serial inside.
    ThreadPool* pool = nullptr;
    /// Chains start their strain solve at the prediction, never warm (the strings'
    /// warmStart): tests compare the two.
    bool cold_strain_starts = false;
    /// Chains' strain solves make Newton iterations only, no chord iterations (src/string/):
    /// tests compare the two.
    bool newton_strain_only = false;
    /// Solves the strings coupled through movable bodies as islands (src/island/); null:
    /// each string alone, the bodies moved by each in turn.
    IslandSolve* islands = nullptr;
};

}  // namespace tearables::detail
