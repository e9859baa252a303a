// The attachments a cloth or a paper sheet is created with (SheetAttachment,
// tearables/sheet_attachment.hpp): one check for both, so that both name the same fields
// the same way and read a vertex index the same way (negative counts from the end).
#pragma once

#include "base/validate.hpp"
#include "sim/rigid_table.hpp"
#include "tearables/sheet_attachment.hpp"

#include <cstddef>
#include <string>
#include <vector>

namespace tearables::detail {

/// Each attachment's vertex as an index in [0, count), in the order given. Throws
/// InvalidInput naming attachments[k].vertex (out of range, or held twice),
/// attachments[k].world (given with a body, or out of the position bound) or
/// attachments[k].local; `owner` ("cloth", "sheet") is the word the messages use.
inline std::vector<std::size_t> resolveSheetAttachments(const std::vector<SheetAttachment>& list, std::size_t count,
                                                        const char* owner) {
    std::vector<std::size_t> vertex(list.size());
    std::vector<std::size_t> held_by(count, 0);  // 1 + the attachment holding a vertex, or 0
    for (std::size_t k = 0; k < list.size(); ++k) {
        const SheetAttachment& a = list[k];
        const std::string field = "attachments[" + std::to_string(k) + "]";
        vertex[k] = resolveSignedIndex(a.vertex, count, field + ".vertex", "vertex", owner, "vertices");
        if (held_by[vertex[k]] != 0)
            throw InvalidInput(field + ".vertex", "vertex " + std::to_string(vertex[k]) + " is already attached (attachments[" +
                                                      std::to_string(held_by[vertex[k]] - 1) + "])");
        held_by[vertex[k]] = k + 1;
        if (a.world) {
            if (a.body.valid()) throw InvalidInput(field + ".world", "give a body or a world point, not both");
            requirePosition(field + ".world", *a.world);
        }
        requirePosition(field + ".local", a.local);
    }
    return vertex;
}

/// Throws InvalidInput("attachments[k].body") when an attachment names a rigid body that
/// `rigids` does not hold.
inline void checkSheetAttachmentBodies(const std::vector<SheetAttachment>& list, const RigidTable& rigids) {
    for (std::size_t k = 0; k < list.size(); ++k) {
        const RigidId body = list[k].body;
        if (body.valid() && !(body.index < rigids.bodies.size() && rigids.used[body.index]))
            throw InvalidInput("attachments[" + std::to_string(k) + "].body", "no such rigid body (id " + std::to_string(body.index) + ")");
    }
}

}  // namespace tearables::detail
