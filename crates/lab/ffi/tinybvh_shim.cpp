// quiver-lab's C entry points into tinybvh's BVH8_CPU and BVH4_CPU (feature `tinybvh`).
//
// This file compiles tinybvh itself (its TINYBVH_IMPLEMENTATION) from whichever tiny_bvh.h
// build.rs found: the snapshot the tinybvh-rs crate ships, or the one QUIVER_TINYBVH_HEADER_DIR
// names (e.g. the newest upstream header). The header's namespace is renamed, so this copy can
// never clash with, or be mixed up with, the one tinybvh-rs compiles from its own snapshot:
// declarations, implementation and flags (-O3 -march=native, C++20) come from one header in one
// translation unit. Nothing here may throw or exit: the Rust side refuses rays tinybvh's
// VALIDATE_RAY would end the process on (NaN) before calling.
#define TINYBVH_IMPLEMENTATION
#define tinybvh quiver_tinybvh
#include "tiny_bvh.h"
#undef tinybvh
namespace tinybvh = quiver_tinybvh;

#include <cstddef>
#include <cstdint>
#include <new>
#include <vector>

namespace {

// One ray as the Rust side hands it over: origin, direction (not normalised: t keeps the
// caller's units), and the far end of the segment.
struct ShimRay {
    float ox, oy, oz;
    float dx, dy, dz;
    float t_max;
};

tinybvh::Ray to_ray(const ShimRay& r) {
    tinybvh::Ray ray;
    ray.O = tinybvh::bvhvec3(r.ox, r.oy, r.oz);
    ray.D = tinybvh::bvhvec3(r.dx, r.dy, r.dz);
    // tinybvh's own reciprocal: a zero component becomes +-1e30, as its Ray constructor does.
    ray.rD = tinybvh::tinybvh_rcp(ray.D);
    ray.mask = RAY_MASK_INTERSECT_ALL;
    ray.instIdx = 0;
    ray.hit.inst = 0;
    ray.hit.t = r.t_max;
    ray.hit.u = 0;
    ray.hit.v = 0;
    ray.hit.prim = 0;
    ray.hit.auxData = nullptr;
    return ray;
}

template <class B>
void* build(const float* vertices, uint32_t tris) {
    B* bvh = new (std::nothrow) B();
    if (bvh == nullptr) return nullptr;
    bvh->Build(reinterpret_cast<const tinybvh::bvhvec4*>(vertices), tris);
    return bvh;
}

// Levels of inner nodes on the deepest root-to-leaf path of a wide BVH (a root leaf: 0).
template <int M>
uint32_t depth(const tinybvh::MBVH<M>& bvh) {
    if (bvh.usedNodes == 0) return 0;
    std::vector<std::pair<uint32_t, uint32_t>> todo{{0, 0}};
    uint32_t deepest = 0;
    while (!todo.empty()) {
        auto [node, d] = todo.back();
        todo.pop_back();
        const auto& n = bvh.mbvhNode[node];
        if (n.isLeaf()) continue;
        if (d + 1 > deepest) deepest = d + 1;
        for (uint32_t i = 0; i < n.childCount && i < uint32_t(M); i++) todo.push_back({n.child[i], d + 1});
    }
    return deepest;
}

template <class B>
int32_t intersect(const void* bvh, const ShimRay* r, float* t, uint32_t* prim) {
    tinybvh::Ray ray = to_ray(*r);
    static_cast<const B*>(bvh)->Intersect(ray);
    if (!(ray.hit.t < r->t_max)) return 0;
    *t = ray.hit.t;
    *prim = ray.hit.prim;
    return 1;
}

template <class B>
int32_t occluded(const void* bvh, const ShimRay* r) {
    return static_cast<const B*>(bvh)->IsOccluded(to_ray(*r)) ? 1 : 0;
}

}  // namespace

extern "C" {

// The header's version macros (1.6.8 and its later development snapshots share one number).
void quiver_tinybvh_version(uint32_t* major, uint32_t* minor, uint32_t* sub) {
    *major = TINY_BVH_VERSION_MAJOR;
    *minor = TINY_BVH_VERSION_MINOR;
    *sub = TINY_BVH_VERSION_SUB;
}

// Traversal counters, when the header was instrumented to keep them (a probe's copy of the
// header that defines QUIVER_TINYBVH_COUNTERS and the counters; never the shipped ones): nodes,
// leaves, triangle lanes tested and stack pushes since the last reset, on all threads. Returns 0
// when the header keeps none.
int32_t quiver_tinybvh_counters(uint64_t* out, int32_t reset) {
#ifdef QUIVER_TINYBVH_COUNTERS
    out[0] = tinybvh::quiver_count_nodes;
    out[1] = tinybvh::quiver_count_leaves;
    out[2] = tinybvh::quiver_count_tris;
    out[3] = tinybvh::quiver_count_pushes;
    if (reset) {
        tinybvh::quiver_count_nodes = tinybvh::quiver_count_leaves = 0;
        tinybvh::quiver_count_tris = tinybvh::quiver_count_pushes = 0;
    }
    return 1;
#else
    (void)out;
    (void)reset;
    return 0;
#endif
}

void* quiver_tinybvh8_build(const float* vertices, uint32_t tris) {
    return build<tinybvh::BVH8_CPU>(vertices, tris);
}
void quiver_tinybvh8_free(void* bvh) { delete static_cast<tinybvh::BVH8_CPU*>(bvh); }
int32_t quiver_tinybvh8_intersect(const void* bvh, const ShimRay* r, float* t, uint32_t* prim) {
    return intersect<tinybvh::BVH8_CPU>(bvh, r, t, prim);
}
int32_t quiver_tinybvh8_occluded(const void* bvh, const ShimRay* r) {
    return occluded<tinybvh::BVH8_CPU>(bvh, r);
}
// Node and leaf data the traversal reads, in 64-byte blocks (used, allocated).
void quiver_tinybvh8_bytes(const void* bvh, uint64_t* used, uint64_t* allocated) {
    const tinybvh::BVH8_CPU* b = static_cast<const tinybvh::BVH8_CPU*>(bvh);
    *used = uint64_t(b->usedBlocks) * 64;
    *allocated = uint64_t(b->allocatedBlocks) * 64;
}

uint32_t quiver_tinybvh8_depth(const void* bvh) {
    return depth(static_cast<const tinybvh::BVH8_CPU*>(bvh)->bvh8);
}

void* quiver_tinybvh4_build(const float* vertices, uint32_t tris) {
    return build<tinybvh::BVH4_CPU>(vertices, tris);
}
void quiver_tinybvh4_free(void* bvh) { delete static_cast<tinybvh::BVH4_CPU*>(bvh); }
int32_t quiver_tinybvh4_intersect(const void* bvh, const ShimRay* r, float* t, uint32_t* prim) {
    return intersect<tinybvh::BVH4_CPU>(bvh, r, t, prim);
}
int32_t quiver_tinybvh4_occluded(const void* bvh, const ShimRay* r) {
    return occluded<tinybvh::BVH4_CPU>(bvh, r);
}
void quiver_tinybvh4_bytes(const void* bvh, uint64_t* used, uint64_t* allocated) {
    const tinybvh::BVH4_CPU* b = static_cast<const tinybvh::BVH4_CPU*>(bvh);
    *used = uint64_t(b->usedBlocks) * 64;
    *allocated = uint64_t(b->allocatedBlocks) * 64;
}

uint32_t quiver_tinybvh4_depth(const void* bvh) {
    return depth(static_cast<const tinybvh::BVH4_CPU*>(bvh)->bvh4);
}

}  // extern "C"
