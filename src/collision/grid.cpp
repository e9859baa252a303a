// The narrow phase every broad phase shares, and ChainTree: see grid.hpp.
#include "collision/grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "collision/capsule.hpp"
#include "base/thread_pool.hpp"

namespace tearables::detail {

bool excludedPair(const CollisionSegment& si, const CollisionSegment& sj, std::uint32_t skip_neighbours) {
    if (si.a == sj.a || si.a == sj.b || si.b == sj.a || si.b == sj.b) return true;
    if (si.chain != sj.chain) return false;
    const std::uint32_t d = si.index_in_chain > sj.index_in_chain ? si.index_in_chain - sj.index_in_chain
                                                                  : sj.index_in_chain - si.index_in_chain;
    return d <= skip_neighbours;
}

bool narrowPhase(const Vec3* x, const std::vector<CollisionSegment>& segs, const SegmentInfo* info, double margin,
                 std::uint32_t i, std::uint32_t j, std::vector<SegmentPair>& out) {
    const CollisionSegment& si = segs[i];
    const CollisionSegment& sj = segs[j];
    const double reach = si.radius + sj.radius + margin;
    // The capsules fit in spheres about the midpoints of radius half_length + radius.
    const double sphere = info[i].half_length + info[j].half_length + reach;
    if ((info[i].mid - info[j].mid).squaredNorm() > sphere * sphere * kPairSlack) return false;
    const SegmentClosest c = closestPointsOfSegments(x[si.a], x[si.b], x[sj.a], x[sj.b]);
    if (!(c.distance < reach)) return true;
    SegmentPair pr;
    pr.first = i;
    pr.second = j;
    pr.s = c.s;
    pr.t = c.t;
    pr.distance = c.distance;
    if (c.distance > 0.0) {
        pr.normal = (c.p - c.q) / c.distance;
    } else {
        // The axes touch: any direction is a normal; take one perpendicular to both axes
        // when they are not parallel, else one perpendicular to an axis, else x.
        const Vec3 d1 = x[si.b] - x[si.a];
        const Vec3 d2 = x[sj.b] - x[sj.a];
        Vec3 n = d1.cross(d2);
        if (!(n.squaredNorm() > 1e-24 * d1.squaredNorm() * d2.squaredNorm())) {
            const Vec3 d = d1.squaredNorm() >= d2.squaredNorm() ? d1 : d2;
            n = d.squaredNorm() > 0.0 ? d.unitOrthogonal() : Vec3::UnitX();
        }
        pr.normal = n.normalized();
    }
    out.push_back(pr);
    return true;
}

namespace {
/// Segments per leaf of a ChainTree: a leaf pair's loops stop at the separation along the
/// rope, where smaller leaves pay a node pair's bounds and callbacks for every few segments
/// along the diagonal (docs/benchmarks-history.md).
constexpr std::uint32_t kLeaf = 16;
constexpr std::size_t kParallelChainSegments = kParallelItems;  // a chain this long is split over the pool
bool boxesOverlap(const Vec3& alo, const Vec3& ahi, const Vec3& blo, const Vec3& bhi) {
    return alo.x() <= bhi.x() && blo.x() <= ahi.x() && alo.y() <= bhi.y() && blo.y() <= ahi.y() && alo.z() <= bhi.z() &&
           blo.z() <= ahi.z();
}

/// How far apart two nodes' boxes of axis end positions are along the coordinate axis that
/// separates them most (<= 0 where the boxes overlap).
double axisSeparation(const ChainTree::NodeBounds& a, const ChainTree::NodeBounds& b) {
    const Vec3 s = (b.lo - a.hi).cwiseMax(a.lo - b.hi);
    return std::max(s.x(), std::max(s.y(), s.z()));
}

/// Nodes of the tree that build() makes over `count` segments.
std::uint32_t treeNodes(std::uint32_t count) {
    return count <= kLeaf ? 1 : 1 + treeNodes(count / 2) + treeNodes(count - count / 2);
}

}  // namespace

std::uint32_t ChainTree::build(std::uint32_t first, std::uint32_t count, std::uint32_t& next) {
    const std::uint32_t index = next++;  // pre-order, as nodes are numbered by treeNodes
    if (count <= kLeaf) {
        Node node;
        node.first = first;
        node.count = count;
        node.lo = seg_lo_[first];
        node.hi = seg_hi_[first];
        for (std::uint32_t k = first + 1; k < first + count; ++k) {
            node.lo = node.lo.cwiseMin(seg_lo_[k]);
            node.hi = node.hi.cwiseMax(seg_hi_[k]);
        }
        if (bounded()) {
            // The bounds over every segment of the leaf, skipped ones too (a bound is all
            // the caller's proof needs; a skipped segment is never paired anyway).
            const std::vector<CollisionSegment>& segs = *segs_;
            NodeBounds b;
            const Vec3& x0 = x_[segs[first].a];
            const Vec3& t0 = sweep_.travel[segs[first].a];
            b.lo = b.hi = x0;
            b.travel_lo = b.travel_hi = t0;
            b.thickness = sweep_.thickness[first];
            b.tangent_lo = Vec3::Constant(1.0);
            b.tangent_hi = Vec3::Constant(-1.0);
            for (std::uint32_t k = first; k < first + count; ++k) {
                for (const std::uint32_t p : {segs[k].a, segs[k].b}) {
                    b.lo = b.lo.cwiseMin(x_[p]);
                    b.hi = b.hi.cwiseMax(x_[p]);
                    b.travel_lo = b.travel_lo.cwiseMin(sweep_.travel[p]);
                    b.travel_hi = b.travel_hi.cwiseMax(sweep_.travel[p]);
                }
                b.thickness = std::max(b.thickness, sweep_.thickness[k]);
                // The axis' direction; a point-like axis may point anywhere, and so may one
                // whose chain does not go on from its end (cross's separation along the
                // chain adds up the segments between two: they must be linked).
                const double length = 2.0 * info_[k].half_length;
                const Vec3 tangent = length > 0.0 ? Vec3((x_[segs[k].b] - x_[segs[k].a]) / length) : Vec3::Zero();
                const bool linked = k + 1 >= segs.size() || segs[k + 1].chain != segs[k].chain || segs[k + 1].a == segs[k].b;
                const bool known = linked && length > 0.0 && tangent.allFinite();
                b.tangent_lo = b.tangent_lo.cwiseMin(known ? tangent : Vec3::Constant(-1.0));
                b.tangent_hi = b.tangent_hi.cwiseMax(known ? tangent : Vec3::Constant(1.0));
            }
            bounds_[index] = b;
        }
        nodes_[index] = node;
    } else {
        const std::uint32_t half = count / 2;
        const std::uint32_t left = build(first, half, next);
        const std::uint32_t right = build(first + half, count - half, next);
        join(index, first, count, left, right);
    }
    return index;
}

void ChainTree::join(std::uint32_t index, std::uint32_t first, std::uint32_t count, std::uint32_t left, std::uint32_t right) {
    Node node;
    node.first = first;
    node.count = count;
    node.left = left;
    node.right = right;
    node.lo = nodes_[left].lo.cwiseMin(nodes_[right].lo);
    node.hi = nodes_[left].hi.cwiseMax(nodes_[right].hi);
    if (bounded()) {
        const NodeBounds& l = bounds_[left];
        const NodeBounds& r = bounds_[right];
        NodeBounds& b = bounds_[index];
        b.lo = l.lo.cwiseMin(r.lo);
        b.hi = l.hi.cwiseMax(r.hi);
        b.travel_lo = l.travel_lo.cwiseMin(r.travel_lo);
        b.travel_hi = l.travel_hi.cwiseMax(r.travel_hi);
        b.tangent_lo = l.tangent_lo.cwiseMin(r.tangent_lo);
        b.tangent_hi = l.tangent_hi.cwiseMax(r.tangent_hi);
        b.thickness = std::max(l.thickness, r.thickness);
    }
    nodes_[index] = node;
}

void ChainTree::splitChain(std::size_t c, ThreadPool& pool, bool self_free) {
    // The root's children are built on two threads, each numbering its nodes from where
    // the serial pre-order would (the left subtree right after the root, the right one
    // after it); then the root's self pairs as three parts, self(left), self(right) and
    // cross(left, right), each into a buffer of its own, appended in the serial order.
    const std::uint32_t first = chain_first_[c], count = chain_count_[c], root = chain_node_[c];
    const std::uint32_t half = count / 2;
    const std::uint32_t left = root + 1, right = left + treeNodes(half);
    pool.forEach(2, [&](std::size_t k) {
        std::uint32_t next = k == 0 ? left : right;
        if (k == 0)
            build(first, half, next);
        else
            build(first + half, count - half, next);
    });
    join(root, first, count, left, right);
    roots_[c] = root;
    chain_out_[c].clear();
    chain_rejects_[c] = 0;
    if (self_free) return;
    std::size_t rejects[3] = {0, 0, 0};
    Vec3 along;
    const Vec3* forward = forwardDirection(root, along) ? &along : nullptr;
    pool.forEach(3, [&](std::size_t k) {
        split_out_[k].clear();
        if (k == 0) self(left, split_out_[k], rejects[k], forward);
        if (k == 1) self(right, split_out_[k], rejects[k], forward);
        if (k == 2) cross(left, right, split_out_[k], rejects[k], forward);
    });
    for (const std::vector<SegmentPair>& part : split_out_) chain_out_[c].insert(chain_out_[c].end(), part.begin(), part.end());
    chain_rejects_[c] = rejects[0] + rejects[1] + rejects[2];
}

void ChainTree::test(std::uint32_t i, std::uint32_t j, std::vector<SegmentPair>& out) const {
    const std::vector<CollisionSegment>& segs = *segs_;
    if (segs[i].skip || segs[j].skip || excludedPair(segs[i], segs[j], skip_)) return;
    if (!boxesOverlap(seg_lo_[i], seg_hi_[i], seg_lo_[j], seg_hi_[j])) return;
    if (reject_) {
        // The narrow phase's own first rejection (the same bounding spheres), then the
        // caller's: what either drops is never output.
        const double reach = segs[i].radius + segs[j].radius + margin_;
        const double sphere = info_[i].half_length + info_[j].half_length + reach;
        if ((info_[i].mid - info_[j].mid).squaredNorm() > sphere * sphere * kPairSlack) return;
        if (reject_(keep_context_, std::min(i, j), std::max(i, j))) return;
    }
    const std::size_t before = out.size();
    narrowPhase(x_, segs, info_.data(), margin_, std::min(i, j), std::max(i, j), out);
    if (keep_ && out.size() > before && !keep_(keep_context_, out.back())) out.pop_back();
}

bool ChainTree::forwardDirection(std::uint32_t index, Vec3& along) const {
    if (!bounded()) return false;
    // The middle of the tangents' box, and the least of t . u over the box (per
    // coordinate, the end that makes the product smallest): every tangent has at least
    // that much along u. Kept only with a clear margin (1e-6) over rounding.
    const NodeBounds& b = bounds_[index];
    const Vec3 middle = 0.5 * (b.tangent_lo + b.tangent_hi);
    const double norm = middle.norm();
    if (!(norm > 0.1)) return false;
    along = middle / norm;
    double least = 0.0;
    for (int c = 0; c < 3; ++c) least += std::min(along[c] * b.tangent_lo[c], along[c] * b.tangent_hi[c]);
    return least > 1e-6;
}

void ChainTree::self(std::uint32_t index, std::vector<SegmentPair>& out, std::size_t& rejects, const Vec3* along) const {
    const Node& node = nodes_[index];
    if (node.left == 0) {
        // Within a leaf, a pair that the separation along `along` settles (see cross). The
        // segments right after i along its chain, within the skip, are never pairs
        // (test's `excluded`): j starts past them.
        const double needed = along ? sweep_.separation(keep_context_, bounds_[index], bounds_[index]) : 0.0;
        const std::vector<CollisionSegment>& segs = *segs_;
        const std::uint32_t end = node.first + node.count;
        for (std::uint32_t i = node.first; i < end; ++i) {
            std::uint32_t start = i + 1;
            while (start < end && start - i <= skip_ && segs[start].index_in_chain - segs[i].index_in_chain == start - i) ++start;
            for (std::uint32_t j = start; j < end; ++j) {
                if (along && (x_[segs[j].a] - x_[segs[i].b]).dot(*along) > needed) break;  // and every later j
                test(i, j, out);
            }
        }
        return;
    }
    Vec3 own;
    if (!along && forwardDirection(index, own)) along = &own;
    self(node.left, out, rejects, along);
    self(node.right, out, rejects, along);
    cross(node.left, node.right, out, rejects, along);
}

void ChainTree::cross(std::uint32_t a, std::uint32_t b, std::vector<SegmentPair>& out, std::size_t& rejects,
                      const Vec3* along) const {
    const Node& na = nodes_[a];
    const Node& nb = nodes_[b];
    if (!boxesOverlap(na.lo, na.hi, nb.lo, nb.hi)) return;
    // Neighbours along one chain closer than the skip are never pairs: ranges entirely
    // within the skip of each other are done.
    const CollisionSegment& sa = (*segs_)[na.first];
    const CollisionSegment& sb = (*segs_)[nb.first];
    if (sa.chain == sb.chain) {
        const std::uint32_t lo_a = sa.index_in_chain, hi_a = lo_a + na.count - 1;
        const std::uint32_t lo_b = sb.index_in_chain, hi_b = lo_b + nb.count - 1;
        const std::uint32_t far = std::max(hi_b > lo_a ? hi_b - lo_a : lo_a - hi_b, hi_a > lo_b ? hi_a - lo_b : lo_b - hi_a);
        if (far <= skip_) return;
    }
    // Along a chain whose segments all point forward along `along` (from a's first to b's
    // last; a's come first), a point of segment i of a and one of segment j of b are at
    // least (x_j,start - x_i,end) . along apart along it: the rest of segment i and the
    // start of segment j only add to that, as do the segments between. The smallest of
    // these, over a's last and b's first segment, bounds every pair's.
    const std::vector<CollisionSegment>& segs = *segs_;
    // The caller's proof that it drops every pair below these two nodes (a rope swinging
    // as a whole: its segments' swept boxes overlap, their relative travel is small): the
    // nodes further apart than `needed` along the chain, or along a coordinate axis.
    const double needed = bounded() ? sweep_.separation(keep_context_, bounds_[a], bounds_[b]) : 0.0;
    const bool apart_along = along && (x_[segs[nb.first].a] - x_[segs[na.first + na.count - 1].b]).dot(*along) > needed;
    if (apart_along || (bounded() && axisSeparation(bounds_[a], bounds_[b]) > needed)) {
        ++rejects;
        return;
    }
    if (na.left == 0 && nb.left == 0) {
        // The separation grows with j (each segment adds to it): past the first j it
        // settles, it settles every later one too.
        for (std::uint32_t i = na.first; i < na.first + na.count; ++i)
            for (std::uint32_t j = nb.first; j < nb.first + nb.count; ++j) {
                if (along && (x_[segs[j].a] - x_[segs[i].b]).dot(*along) > needed) break;
                test(i, j, out);
            }
        return;
    }
    if (nb.left == 0 || (na.left != 0 && na.count >= nb.count)) {
        cross(na.left, b, out, rejects, along);
        cross(na.right, b, out, rejects, along);
    } else {
        cross(a, nb.left, out, rejects, along);
        cross(a, nb.right, out, rejects, along);
    }
}

void ChainTree::findPairs(const Vec3* positions, const std::vector<CollisionSegment>& segments, double margin,
                          std::vector<SegmentPair>& out, std::uint32_t skip_neighbours, ThreadPool* pool, Filter keep,
                          const void* context, Reject reject, const Sweep* sweep, const std::uint8_t* self_free) {
    out.clear();
    keep_ = keep;
    reject_ = reject;
    sweep_ = sweep && sweep->separation && sweep->travel && sweep->thickness ? *sweep : Sweep{};
    keep_context_ = context;
    x_ = positions;
    segs_ = &segments;
    margin_ = margin;
    skip_ = skip_neighbours;
    auto each = [pool](std::size_t count, auto&& fn) {
        if (pool) pool->forEach(count, fn);
        else
            for (std::size_t i = 0; i < count; ++i) fn(i);
    };
    const std::size_t m = segments.size();
    seg_lo_.resize(m);
    seg_hi_.resize(m);
    info_.resize(m);
    const double inf = std::numeric_limits<double>::infinity();
    const std::size_t chunks = std::min<std::size_t>(m, 64);
    each(chunks, [&](std::size_t chunk) {
        for (std::size_t k = m * chunk / chunks; k < m * (chunk + 1) / chunks; ++k) {
            const CollisionSegment& sg = segments[k];
            const Vec3& a = positions[sg.a];
            const Vec3& b = positions[sg.b];
            info_[k].mid = 0.5 * (a + b);
            info_[k].length2 = (b - a).squaredNorm();
            info_[k].half_length = 0.5 * std::sqrt(info_[k].length2);
            if (sg.skip) {
                seg_lo_[k] = Vec3::Constant(inf);
                seg_hi_[k] = Vec3::Constant(-inf);
                continue;
            }
            const Vec3 grow = Vec3::Constant(sg.radius + 0.5 * margin);
            seg_lo_[k] = a.cwiseMin(b) - grow;
            seg_hi_[k] = a.cwiseMax(b) + grow;
        }
    });
    // One tree per chain (runs of equal `chain`); node 0 is a dummy so that 0 means "leaf".
    // Each chain's nodes are a range of their own, numbered beforehand.
    chain_first_.clear();
    chain_count_.clear();
    chain_node_.clear();
    std::uint32_t nodes = 1;
    for (std::size_t first = 0; first < m;) {
        std::size_t last = first + 1;
        while (last < m && segments[last].chain == segments[first].chain) ++last;
        chain_first_.push_back(static_cast<std::uint32_t>(first));
        chain_count_.push_back(static_cast<std::uint32_t>(last - first));
        chain_node_.push_back(nodes);
        nodes += treeNodes(static_cast<std::uint32_t>(last - first));
        first = last;
    }
    nodes_.resize(nodes);
    nodes_[0] = Node{};
    if (bounded()) bounds_.resize(nodes);
    const std::size_t chains = chain_first_.size();
    if (chain_out_.size() < chains) chain_out_.resize(chains);
    roots_.resize(chains);
    chain_rejects_.resize(chains);
    // A chain of kParallelChainSegments or more, where the pool runs in parallel, is split
    // over it by itself (splitChain: a long rope alone uses every core); the others run
    // one per thread. The nodes and pairs are the same either way.
    auto big = [&](std::size_t c) { return pool && pool->parallel() && chain_count_[c] >= kParallelChainSegments; };
    each(chains, [&](std::size_t c) {
        if (big(c)) return;
        std::uint32_t next = chain_node_[c];
        roots_[c] = build(chain_first_[c], chain_count_[c], next);
        chain_out_[c].clear();
        chain_rejects_[c] = 0;
        if (!(self_free && self_free[c])) self(roots_[c], chain_out_[c], chain_rejects_[c]);
    });
    for (std::size_t c = 0; c < chains; ++c)
        if (big(c)) splitChain(c, *pool, self_free && self_free[c]);
    for (std::size_t c = 0; c < chains; ++c) out.insert(out.end(), chain_out_[c].begin(), chain_out_[c].end());
    // Chains against each other: sweep the root boxes along the axis on which their
    // centres spread most (strings side by side all overlap along their own length: swept
    // along it, every root met every other), sorted by their lower bound on it, ties by
    // position in the list: deterministic. The pairs are the same on any axis; only the
    // order of the output changes.
    int axis = 0;
    if (roots_.size() > 2) {
        Vec3 mean = Vec3::Zero(), square = Vec3::Zero();
        for (std::uint32_t r : roots_) {
            const Vec3 c = 0.5 * (nodes_[r].lo + nodes_[r].hi);
            mean += c;
            square += c.cwiseProduct(c);
        }
        const double k = static_cast<double>(roots_.size());
        const Vec3 spread = square / k - (mean / k).cwiseProduct(mean / k);
        if (spread.allFinite()) spread.maxCoeff(&axis);
    }
    order_ = roots_;
    std::sort(order_.begin(), order_.end(), [&](std::uint32_t l, std::uint32_t r) {
        const double a = nodes_[l].lo[axis], b = nodes_[r].lo[axis];
        return a < b || (a == b && l < r);
    });
    // The pairs of roots the sweep meets, in its order; each pair's descent on the pool
    // into a buffer of its own, appended in that order.
    root_pairs_.clear();
    for (std::size_t i = 0; i < order_.size(); ++i) {
        const Node& a = nodes_[order_[i]];
        for (std::size_t j = i + 1; j < order_.size() && nodes_[order_[j]].lo[axis] <= a.hi[axis]; ++j)
            root_pairs_.emplace_back(std::min(order_[i], order_[j]), std::max(order_[i], order_[j]));
    }
    if (root_out_.size() < root_pairs_.size()) root_out_.resize(root_pairs_.size());
    root_rejects_.resize(root_pairs_.size());
    each(root_pairs_.size(), [&](std::size_t k) {
        root_out_[k].clear();
        root_rejects_[k] = 0;
        cross(root_pairs_[k].first, root_pairs_[k].second, root_out_[k], root_rejects_[k]);
    });
    for (std::size_t k = 0; k < root_pairs_.size(); ++k) out.insert(out.end(), root_out_[k].begin(), root_out_[k].end());
}

std::size_t ChainTree::lastNodeRejects() const {
    std::size_t n = 0;
    for (std::size_t c = 0; c < roots_.size(); ++c) n += chain_rejects_[c];
    for (std::size_t k = 0; k < root_pairs_.size(); ++k) n += root_rejects_[k];
    return n;
}

}  // namespace tearables::detail
