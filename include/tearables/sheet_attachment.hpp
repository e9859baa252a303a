// tearables: what holds a vertex of a cloth or a paper sheet at creation (ClothDesc::attachments,
// PaperDesc::attachments). The same words as a scene's attachments (docs/SCENE_FORMAT.md, "Words").
#pragma once

#include "tearables/ids.hpp"
#include "tearables/types.hpp"

#include <optional>

namespace tearables {

/// A vertex of a cloth or a sheet glued to a rigid body, or pinned to a world point, from
/// creation on (at most one per vertex). The runtime calls (World::attachClothToRigid,
/// attachPaperToPoint, ...) hold a vertex the same way later.
struct SheetAttachment {
    /// The vertex's flat index: a grid's j * resolution[0] + i (ClothDesc::vertex,
    /// PaperDesc::gridVertex) or a mesh's vertex; negative counts from the end (-1 = the last).
    int vertex = 0;
    /// Glued to this rigid body proxy, two-way (the body carries what the vertex pulls, with
    /// its mass and inertia), at `local`; invalid (the default): pinned in the world.
    RigidId body;
    Vec3 local = Vec3::Zero();   ///< with body: the point in the body's frame (from its centre of mass), m, each coordinate in [-1e6, 1e6]
    std::optional<Vec3> world;   ///< without body: the world point, m, each coordinate in [-1e6, 1e6]; default: where the vertex starts
};

}  // namespace tearables
