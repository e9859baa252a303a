// Chain shape matching (CSM) goal positions, the stateless kernel behind the string's
// bending stiffness (Strings, Sec. 3; Rungjiratananon et al. 2010).
//
// A piece of string is a chain of particles. Region k of the piece [first, last] holds
// the particles max(first, k-w) .. min(last, k+w), one region centred on every particle.
// Each region is matched rigidly to its rest shape; a particle's goal is the average of
// the goals its regions give it. See shape_matching.cpp for the details (per-region mass,
// the polar decomposition and the O(1)-per-region moment sums).
#pragma once

#include "tearables/types.hpp"

#include <cstddef>
#include <vector>

namespace tearables::detail {

class ThreadPool;

/// Mass moments of a run of particles about a reference point pair (p, p0):
/// m = sum m_i, mx = sum m_i (x_i - p), mx0 = sum m_i (x0_i - p0),
/// mxx0 = sum m_i (x_i - p)(x0_i - p0)^T.
struct CsmMoments {
    double m = 0.0;
    Vec3 mx = Vec3::Zero();
    Vec3 mx0 = Vec3::Zero();
    Mat3 mxx0 = Mat3::Zero();
};

/// Working memory of chainShapeMatchingGoals. The vectors only grow (resized when too
/// small), so a scratch reused across calls and steps makes the kernel allocation-free.
/// After a call, entry j (0 <= j <= last-first) of `rotation`, `centroid` and
/// `rest_centroid` describes region first+j of that call's piece: its optimal rotation
/// R_k, its current centroid c_k and its rest centroid c0_k (per-region mass weighted).
struct CsmScratch {
    std::vector<Mat3> rotation;
    std::vector<Vec3> centroid;
    std::vector<Vec3> rest_centroid;
    /// One chunk's working memory (chainShapeMatchingGoals does a long piece in chunks),
    /// one per range of chunks on the pool.
    struct Work {
        std::vector<CsmMoments> prefix;  ///< moments from the start of a block to a particle
        std::vector<CsmMoments> suffix;  ///< moments from a particle to the end of its block
        std::vector<Mat3> rotation;      ///< a chunk's regions (those beyond it included)
        std::vector<Vec3> centroid;
        std::vector<Vec3> rest_centroid;
        std::vector<double> line_prefix, line_suffix;  ///< straightChainShapeMatchingGoals' sums
        std::vector<Vec3> direction;                   ///< its regions' R v
    };
    std::vector<Work> work;
};

/// The particles of a piece chainShapeMatchingGoals does at a time (rounded down to whole
/// blocks of 2w+1): ~0.4 kB of moments and regions each, so that a chunk stays in the
/// core's own cache through its four passes.
constexpr std::size_t kCsmChunkParticles = 1024;

/// Computes CSM goal positions for the particles first..last (inclusive) of one piece of
/// chain. x, rest and mass are indexed absolutely (x[first] .. x[last] are read; a torn
/// string is several pieces: call once per piece); goal[first..last] are written, nothing
/// else is. mass > 0 (make colliding particles 3x heavier here, Strings Sec. 6). w >= 1 is
/// the region half-width. The cost is O(n) regions of O(1) each (one 3x3 polar factor each)
/// plus O(n w) for blending; no heap allocation when `scratch` is already large enough.
/// A piece of kParallelItems (thread_pool.hpp) particles or more is split over `pool`
/// (may be null), with the same bits as serially. Throws InvalidInput if w < 1 or first > last.
void chainShapeMatchingGoals(const Vec3* x, const Vec3* rest, const double* mass, std::size_t first,
                             std::size_t last, int w, Vec3* goal, CsmScratch& scratch, ThreadPool* pool = nullptr);

/// chainShapeMatchingGoals for a piece whose rest shape is straight: rest[first..last] lie
/// on one line, in order along the unit vector `direction` v. Every region's A is then
/// rank 1, A = a v^T with a = sum m~ (x - c) ((x0 - c0) . v), and the rotation it takes
/// maps v to a / |a| (for rank 1, csmRotation's smallest such rotation; the rotation about
/// the line does not matter, the rest offsets lie along it). So a region's goals are
/// c + ((x0_i - c0) . v) a / |a|, from 8 moment sums instead of 16 and without a polar
/// factor. The goals agree with chainShapeMatchingGoals' to rounding (tested); the
/// scratch's per-region arrays are not written. Throws as chainShapeMatchingGoals, and
/// InvalidInput if w > 8 (the largest half-width a string takes, StringDesc::csm_half_width).
void straightChainShapeMatchingGoals(const Vec3* x, const Vec3* rest, const double* mass, std::size_t first,
                                     std::size_t last, int w, const Vec3& direction, Vec3* goal, CsmScratch& scratch,
                                     ThreadPool* pool = nullptr);

/// The rotational part of a 3x3 matrix A (the R in A = R S, S symmetric, det R = +1) as
/// used by chainShapeMatchingGoals: it maximises tr(R^T A). When A has rank <= 1 (all
/// particles of a region collinear now or at rest) the rotation about the line is
/// undetermined; then the rotation closest to identity (smallest angle) among the optimal
/// ones is returned, and identity when A = 0 or not finite. Computed without an SVD where
/// a cheaper method is sure to give the same rotation to rounding (see shape_matching.cpp).
Mat3 csmRotation(const Mat3& a);

}  // namespace tearables::detail
