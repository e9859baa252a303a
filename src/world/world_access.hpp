// Access to the whole state of a World for snapshots (src/world/snapshot.cpp): the parts
// that persist from one step to the next: strings, cloths, paper sheets and the world's own.
#pragma once

#include "cloth/cloth_state.hpp"
#include "collision/grid.hpp"
#include "paper/sheet.hpp"
#include "string/string_pairs.hpp"
#include "string/string_state.hpp"
#include "tearables/world.hpp"

#include <cstdint>
#include <vector>

namespace tearables::detail {

/// Pointers into a World's state; valid while the world lives.
struct WorldParts {
    WorldSettings* settings;
    std::vector<StringState>* strings;          ///< by slot (dead slots included: ids stay)
    std::vector<ClothState>* cloths;            ///< by slot (ClothSystem's, dead slots included)
    std::vector<PaperSheet>* papers;            ///< by slot (PaperSystem's, dead slots included)
    RigidTable* rigids;                         ///< by slot
    std::vector<Event>* pending;                ///< emitted between steps, reported with the next
    std::vector<Event>* events;                 ///< of the last step
    std::vector<StringPairContact>* previous_pairs;///< string-string warm start
    std::vector<PairKey>* deep_pairs;           ///< string-string pairs not yet apart
    double* time;
    std::int64_t* steps;
};

struct WorldAccess {
    static WorldParts parts(World& world);

    // The string-string search, for tests: whether whole node pairs of the tree are dropped
    // (ChainTree::Sweep; on by default), how many the last step dropped, and the pairs of
    // the last step's swept search that were not dropped (contacts and deep pairs).
    static void setStringNodePruning(World& world, bool on);
    static std::size_t lastStringNodeRejects(const World& world);
    // The search's proof that a nearly straight string has no self pairs (selfPairFree):
    // off, every string's self pairs are searched; and how many strings it held for in
    // the last step.
    static void setStraightStringsSkip(World& world, bool on);
    static std::size_t lastSelfFreeStrings(const World& world);
    static const std::vector<SegmentPair>& lastStringSearchPairs(const World& world);
    // Every joint string solve's Newton steps by the sparse factorisation of the whole
    // cluster (ClusterScratch::always_sparse), for tests that compare it with Woodbury's.
    static void setSparseJointSteps(World& world, bool on);
    // Chains' strain solves started at the prediction instead of the warm start
    // (StepContext::cold_strain_starts), for tests that compare the two.
    static void setColdStrainStarts(World& world, bool on);
    // Chains' strain solves by Newton iterations only, without chord iterations
    // (StepContext::newton_strain_only), for tests that compare the two.
    static void setNewtonStrainOnly(World& world, bool on);
};

}  // namespace tearables::detail
