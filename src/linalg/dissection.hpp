// A fill-reducing order for sparse factorisations of meshes on a grid.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace tearables::detail {

/// Nested-dissection order (George 1973) of items at integer grid coordinates `at`: the
/// items of a box are split by a line of the box's longer axis, coordinates [X, X + width)
/// with X = `phase` modulo `modulus`, into the two sides (ordered first, recursively) and
/// the line (last). For a weave: vertices with width 2 (bending springs reach two cells),
/// edges at doubled midpoint coordinates with width 1 on odd lines (the warp edges crossing
/// between two vertex columns separate the edges on either side: no vertex is on both).
/// On a grid this gives the least fill a sparse Cholesky can have, up to a constant (on
/// the cloth's yarns AMD gives 23% more; docs/benchmarks-history.md).
std::vector<std::uint32_t> gridDissection(const std::vector<std::array<int, 2>>& at, int width, int modulus, int phase);

}  // namespace tearables::detail
