// tearables: everyday controls of a string beyond its descriptor: a particle inserted
// anywhere along a string (to attach there) and the particles' velocities. (The hanging
// shape between two points: StringDesc::between; materials by name: presets.hpp.)
#pragma once

#include "tearables/ids.hpp"
#include "tearables/string.hpp"
#include "tearables/world.hpp"

#include <vector>

namespace tearables {

/// Inserts a particle at fraction `s` of the string's length along its points (arc
/// length, 0 = first particle, 1 = last) by splitting the segment it falls in, and returns
/// its index: attach a body there (BulletWorld::attach) to hold the string at any point.
/// Where s falls within 1e-9 of the length on an existing particle, that particle's index
/// is returned and nothing changes. The new particle's segments carry the split segment's
/// per-segment settings (twist_half_width); particle_masses with a non-negative index
/// after it are moved on by one (negative ones count from the end and stay). Throws
/// InvalidInput("s": finite, in [0, 1]; or the descriptor's field when `desc` is invalid),
/// and changes nothing then.
int insertParticle(StringDesc& desc, double s);

/// Sets the velocities of a string's particles, m/s: one for all, or one per particle (each
/// finite, |v| at most WorldSettings::max_speed). Held particles (pinned, glued) move with
/// what holds them and keep theirs. Throws InvalidInput ("string"; "velocities": wrong
/// count; "velocities[i]": not finite or too fast) and changes nothing then.
void setVelocities(World& world, StringId id, const std::vector<Vec3>& velocities);

/// Sets segment `segment`'s rest length (negative counts from the end), m, in
/// [1e-6, 1e6]: its strain limit and plastic state scale with it. Throws InvalidInput
/// ("string", "segment", "length", "mode") and changes nothing then.
void setRestLength(World& world, StringId id, int segment, double length, RestMass mode = RestMass::Conserve);

/// A winch at a pinned end (0 or -1) takes in (`change` < 0) or pays out (`change` > 0)
/// that much rope, m: the segment at the winch shortens or lengthens. Hauled in to 1% of
/// its length at creation, a segment stays that short and its far particle is pinned at
/// the winch too (the rope wound on the drum), and the next segment shortens; a pay-out
/// lengthens the segment at the winch's side of the rope still out. Throws InvalidInput
/// ("string"; "end": not 0 or -1, or not pinned; "change": not finite or over 1e6 m;
/// "mode") and changes nothing then.
void reel(World& world, StringId id, int end, double change, RestMass mode = RestMass::Conserve);

}  // namespace tearables
