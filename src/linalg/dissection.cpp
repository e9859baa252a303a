#include "linalg/dissection.hpp"

#include <algorithm>
#include <utility>

namespace tearables::detail {

namespace {

/// Boxes of at most this many items are not split further (their order hardly matters).
constexpr std::size_t kDissectionLeaf = 8;

struct Dissection {
    const std::vector<std::array<int, 2>>& at;
    int width, modulus, phase;
    std::vector<std::uint32_t>& out;

    void leaf(std::vector<std::uint32_t>& items) {
        std::sort(items.begin(), items.end());
        out.insert(out.end(), items.begin(), items.end());
    }

    void run(std::vector<std::uint32_t> items) {
        if (items.size() <= kDissectionLeaf) return leaf(items);
        int lo[2] = {at[items[0]][0], at[items[0]][1]}, hi[2] = {lo[0], lo[1]};
        for (std::uint32_t i : items)
            for (int a = 0; a < 2; ++a) {
                lo[a] = std::min(lo[a], at[i][a]);
                hi[a] = std::max(hi[a], at[i][a]);
            }
        const int axis = hi[0] - lo[0] >= hi[1] - lo[1] ? 0 : 1;
        int line = lo[axis] + (hi[axis] - lo[axis] + 1 - width) / 2;  // the middle
        while (((line - phase) % modulus + modulus) % modulus != 0) ++line;
        std::vector<std::uint32_t> before, after, separator;
        for (std::uint32_t i : items) {
            const int x = at[i][axis];
            (x < line ? before : x >= line + width ? after : separator).push_back(i);
        }
        if (before.size() == items.size() || after.size() == items.size()) return leaf(items);  // no split
        items.clear();
        items.shrink_to_fit();
        run(std::move(before));
        run(std::move(after));
        leaf(separator);
    }
};

}  // namespace

std::vector<std::uint32_t> gridDissection(const std::vector<std::array<int, 2>>& at, int width, int modulus, int phase) {
    std::vector<std::uint32_t> out, all(at.size());
    out.reserve(at.size());
    for (std::size_t i = 0; i < at.size(); ++i) all[i] = static_cast<std::uint32_t>(i);
    Dissection{at, width, modulus, phase, out}.run(std::move(all));
    return out;
}

}  // namespace tearables::detail
