// Union-find's root with path halving (Tarjan and van Leeuwen 1984): each visited entry
// is pointed at its grandparent on the way up.
#pragma once

#include <vector>

namespace tearables::detail {

/// The root of i in the forest `parent` (parent[r] == r at a root), halving the path.
template <class Index>
Index unionRoot(std::vector<Index>& parent, Index i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
}

}  // namespace tearables::detail
