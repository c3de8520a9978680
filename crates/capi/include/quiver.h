/*
 * quiver.h: the C API of quiver, a CPU ray-tracing library (BVH builds, ray and point
 * queries, saved BVHs, instanced worlds).
 *
 * Build the library with `cargo build --release -p quiver-capi`: target/release holds
 * libquiver_capi.a (static) and libquiver_capi.so / .dylib / quiver_capi.dll (shared).
 * Link the static library with `-lpthread -ldl -lm` on Linux.
 *
 * Conventions, for every function below:
 * - Functions return a QvStatus: QV_OK, or why nothing was done; qv_last_error() then
 *   names the argument (and vertex, triangle or instance) at fault.
 * - A pointer argument is never read when NULL: NULL is refused with QV_NULL_POINTER,
 *   except where a function says NULL is allowed (an array whose count is 0 may be NULL).
 * - Handles (QvBvh*, QvWorldBuilder*, QvWorld*) are created by one function and freed by
 *   another; passing a freed or foreign pointer is undefined behaviour, as in any C API.
 * - Queries on one handle may run on any number of threads at once. A function that
 *   changes a handle (refit, edits, builder calls, free) needs it to itself: no other call
 *   on that handle may run meanwhile.
 * - Array queries (qv_*_hits) run in parallel on the library's own worker threads (rayon's
 *   global pool: one thread per core, or RAYON_NUM_THREADS), and return when all are done.
 * - No Rust panic crosses into C: a panic inside quiver returns QV_PANIC with its message
 *   (a bug in quiver: please report it; Rust's default panic hook also prints it to stderr).
 *   This holds for the library as built by Cargo (panic = "unwind").
 */
#ifndef QUIVER_H
#define QUIVER_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The id a hit reports where it names nothing: no hit, or the geometry and instance of a
 * hit in a lone BVH. */
#define QV_INVALID_ID UINT32_MAX

/* What a call did. */
typedef enum QvStatus {
    /* Done. */
    QV_OK = 0,
    /* A pointer argument that must not be NULL was NULL. */
    QV_NULL_POINTER = 1,
    /* An argument out of range: a size that overflows, an unknown geometry or instance id,
     * a transform that is not finite or not invertible, a refit of a loaded BVH. */
    QV_INVALID_ARGUMENT = 2,
    /* A mesh that cannot be built or refit: a stride shorter than its element, an index
     * past the vertices, a non-finite vertex coordinate, more than UINT32_MAX triangles. */
    QV_BAD_MESH = 3,
    /* Reading or writing a file failed. */
    QV_IO = 4,
    /* A file that is not a saved quiver BVH, or one damaged. */
    QV_BAD_FILE = 5,
    /* quiver panicked (a bug). The objects passed are unchanged, or freed where the
     * function frees them. */
    QV_PANIC = 6
} QvStatus;

/* A ray: the points org + t * dir for t in [t_min, t_max] (closed). A world's instance is
 * seen only by rays whose mask shares a bit with the instance's; a lone BVH ignores it. */
typedef struct QvRay {
    float org[3];
    /* Start of the interval; negative values count as 0. */
    float t_min;
    /* Direction, not necessarily unit length: t is measured in its units. */
    float dir[3];
    /* End of the interval; INFINITY for none. */
    float t_max;
    /* 0xFFFFFFFF: every instance. */
    uint32_t mask;
    /* When in the shutter the ray is shot, 0 to 1: moving instances are met where they are
     * then (clamped; NaN counts as 0). 0 for a scene without motion. */
    float time;
} QvRay;

/* A ray's hit. On a miss: prim, geometry and instance are QV_INVALID_ID, t is INFINITY,
 * u and v are 0; test prim == QV_INVALID_ID. Ties in t go to the lower instance, then the
 * lower triangle. */
typedef struct QvHit {
    /* Distance along the ray, in units of its direction. */
    float t;
    /* Barycentric weights of the triangle's second and third vertex. */
    float u, v;
    /* The triangle: its index in the mesh's index buffer. */
    uint32_t prim;
    /* Worlds: the geometry and instance hit. A lone BVH: QV_INVALID_ID. */
    uint32_t geometry, instance;
} QvHit;

/* The nearest point of a BVH's or a world's triangles to a query point. On a miss (nothing
 * within the distance asked): prim, geometry and instance are QV_INVALID_ID, distance
 * INFINITY, the rest 0. */
typedef struct QvPointHit {
    /* The point, in world space for a world. */
    float point[3];
    /* Distance from the query point to point (in world space for a world). */
    float distance;
    /* Barycentric weights of the triangle's second and third vertex at point. */
    float u, v;
    /* The triangle: its index in the mesh's index buffer. */
    uint32_t prim;
    /* Worlds: the geometry and instance of the triangle. A lone BVH: QV_INVALID_ID. */
    uint32_t geometry, instance;
} QvPointHit;

/* A build preset: how long a build takes against how fast its BVH is traced. */
typedef enum QvQuality {
    /* Binned SAH: the default. */
    QV_QUALITY_DEFAULT = 0,
    /* The LBVH builder: several times faster to build, somewhat slower to trace. */
    QV_QUALITY_FAST = 1,
    /* Spatial splits: 3 to 4 times the default's build time; faster to trace where
     * triangles are long or overlap. */
    QV_QUALITY_HIGH = 2
} QvQuality;

/* How a BVH is built. Functions taking a `const QvBuildOptions *` accept NULL for the
 * defaults ({QV_QUALITY_DEFAULT, NULL}), except where they say otherwise; the struct and
 * the layout string are read during the call only. */
typedef struct QvBuildOptions {
    /* A QvQuality value (a uint32_t, so a value outside the enum is refused, not
     * undefined). */
    uint32_t quality;
    /* NULL for the preset's layout (bvh8-dfs), else a NUL-terminated layout name:
     * "bvh8-dfs", "bvh4-quant", "bvh4-dfs", "bvh4-subtree", "bvh2-dfs", "bvh2-bfs",
     * "bvh2-shuffled", "bvh2-subtree", "bvh2-subtree-page", "bvh2-compact",
     * "bvh2-compact-page" (as quiver's command line spells them). */
    const char *layout;
} QvBuildOptions;

/* A BVH over one indexed triangle mesh (opaque). */
typedef struct QvBvh QvBvh;
/* A world being collected: meshes, instances, filters (opaque). */
typedef struct QvWorldBuilder QvWorldBuilder;
/* Geometries placed by instances under one top-level BVH (opaque). */
typedef struct QvWorld QvWorld;

/* A geometry's hit filter: returns nonzero to keep `candidate`, 0 to let the ray pass
 * through it. `candidate` is valid only during the call; `user` is the pointer given with
 * the filter.
 * Contract the caller accepts by setting one:
 * - It is called from any thread, several calls at once (queries run in parallel), always
 *   with the same `user`: it must be thread-safe, and `user` shared (read-only, or
 *   synchronised by the caller).
 * - It must not unwind: no C++ exception and no longjmp may leave it (that aborts or is
 *   undefined behaviour).
 * - It may be called for the same candidate more than once and in any order, so it should
 *   answer from the candidate alone. It must not call qv_ functions on the same world.
 * - It and `user` must stay valid for as long as the world lives. */
typedef int (*QvFilterFn)(void *user, const QvHit *candidate);

/* The message of the last refused call on this thread (it names the function, the
 * argument, and the vertex, triangle or instance at fault), or "" after a call that
 * succeeded. Never NULL. Valid until the next qv_ call on this thread; copy it to keep it. */
const char *qv_last_error(void);

/* ---- BVHs ---------------------------------------------------------------------------- */

/* Builds a BVH over an indexed triangle mesh. Vertex i's position is the three floats at
 * byte i * vertex_stride_bytes of `vertices` (12 for packed positions; larger to read the
 * positions out of an interleaved vertex struct whose first field they are; any alignment).
 * Triangle t's vertex indices are the three uint32_t at byte t * index_stride_bytes of
 * `indices` (12 for packed triples). Both buffers are read during the call only (copied).
 * Hits name triangle t as `prim`.
 * `vertices` may be NULL only when vertex_count is 0, `indices` only when triangle_count
 * is 0 (an empty BVH, hit by nothing).
 * On QV_OK, *out is the new BVH: free it with qv_bvh_free. On failure *out is NULL (when
 * `out` is not NULL).
 * Errors: QV_NULL_POINTER; QV_BAD_MESH for a stride below 12 bytes, an index past the
 * vertices (the message names the triangle, corner and index), a non-finite vertex
 * coordinate (it names the vertex), more than UINT32_MAX triangles; QV_INVALID_ARGUMENT
 * when count * stride overflows. */
QvStatus qv_bvh_build_indexed(const float *vertices, size_t vertex_count,
                              size_t vertex_stride_bytes, const uint32_t *indices,
                              size_t triangle_count, size_t index_stride_bytes, QvBvh **out);

/* As qv_bvh_build_indexed (which is this with options NULL), built with *options: a preset
 * and a layout (see QvBuildOptions); options may be NULL for the defaults. Presets and
 * layouts differ in build time, trace speed and footprint (qv_bvh_footprint), not in the
 * hits a query reports.
 * Errors: as qv_bvh_build_indexed; QV_INVALID_ARGUMENT for options.quality not a QvQuality
 * (the message names options.quality), or options.layout not UTF-8 or not a layout name (the
 * message names options.layout and lists the names). */
QvStatus qv_bvh_build_indexed_with(const float *vertices, size_t vertex_count,
                                   size_t vertex_stride_bytes, const uint32_t *indices,
                                   size_t triangle_count, size_t index_stride_bytes,
                                   const QvBuildOptions *options, QvBvh **out);

/* Frees a BVH. NULL is ignored. The BVH must not be in use on another thread. */
void qv_bvh_free(QvBvh *bvh);

/* The closest hit of *ray into *hit (the miss record when nothing is hit).
 * Errors: QV_NULL_POINTER. */
QvStatus qv_bvh_closest_hit(const QvBvh *bvh, const QvRay *ray, QvHit *hit);

/* Whether anything is hit within *ray's interval: *occluded is 1 or 0 (stops at the first
 * hit found). Errors: QV_NULL_POINTER. */
QvStatus qv_bvh_any_hit(const QvBvh *bvh, const QvRay *ray, int *occluded);

/* The closest hits of rays[0..n] into hits[0..n], traced in parallel (packets of coherent
 * rays where they are). Each answer is exactly qv_bvh_closest_hit's. The arrays must not
 * overlap; both may be NULL when n is 0.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT when n elements overflow the address space. */
QvStatus qv_bvh_closest_hits(const QvBvh *bvh, const QvRay *rays, size_t n, QvHit *hits);

/* Whether each of rays[0..n] hits anything: occluded[i] is 1 or 0; traced in parallel.
 * The arrays must not overlap; both may be NULL when n is 0.
 * Errors: as qv_bvh_closest_hits. */
QvStatus qv_bvh_any_hits(const QvBvh *bvh, const QvRay *rays, size_t n, uint8_t *occluded);

/* Refits the BVH to new vertex positions for the same triangles (the index buffer given to
 * qv_bvh_build_indexed, kept since): the tree stays, its boxes follow the vertices; queries
 * then answer exactly for the new positions. Vertices are read as qv_bvh_build_indexed
 * reads them; vertex_count may differ from the build's as long as every index names one.
 * Changes the BVH: no other call on it may run meanwhile.
 * Errors: QV_NULL_POINTER; QV_BAD_MESH (stride, an index past the new vertices, a
 * non-finite coordinate); QV_INVALID_ARGUMENT for a BVH from qv_bvh_load (it keeps no index
 * buffer) or an overflowing size. On failure the BVH is unchanged. */
QvStatus qv_bvh_refit(QvBvh *bvh, const float *vertices, size_t vertex_count,
                      size_t vertex_stride_bytes);

/* The point of the BVH's triangles nearest point[0..3] within max_distance (inclusive;
 * INFINITY for any distance) into *hit: the miss record when none lies that near, and for
 * a non-finite point or a NaN or negative max_distance. Ties go to the lower triangle.
 * Errors: QV_NULL_POINTER. */
QvStatus qv_bvh_closest_point(const QvBvh *bvh, const float point[3], float max_distance,
                              QvPointHit *hit);

/* Writes the BVH to the file `path` (a NUL-terminated file name, created or replaced all or
 * nothing: written beside it as a temporary file, then renamed over it, so a failed save
 * leaves an existing file as it was) in quiver's file format (docs/file-format.md):
 * qv_bvh_load reads it on any machine of the same byte order. The index buffer is not saved.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT (a path that names no file, such as "/");
 * QV_IO (the message names the path and the OS error). */
QvStatus qv_bvh_save(const QvBvh *bvh, const char *path);

/* Reads a BVH qv_bvh_save wrote from the file `path`, checked completely (checksum and
 * structure) before it is returned. On QV_OK, *out is the new BVH: free it with
 * qv_bvh_free; it answers every query as the saved one did, but cannot be refit. On failure
 * *out is NULL (when `out` is not NULL).
 * Errors: QV_NULL_POINTER; QV_IO; QV_BAD_FILE (not a saved BVH, damaged, another format
 * version or byte order: the message says which). */
QvStatus qv_bvh_load(const char *path, QvBvh **out);

/* The bytes the BVH holds into *bytes: its nodes, its leaves' triangles and triangle ids,
 * and what its layout keeps for refits. Not counted: the copy of the index buffer kept for
 * qv_bvh_refit (12 bytes a triangle; none for a loaded BVH) and the handle itself.
 * Errors: QV_NULL_POINTER. */
QvStatus qv_bvh_footprint(const QvBvh *bvh, size_t *bytes);

/* ---- Worlds ---------------------------------------------------------------------------- */

/* Starts an empty world builder. On QV_OK *out is the builder: pass it to qv_world_build,
 * or free it with qv_world_builder_free. Errors: QV_NULL_POINTER. */
QvStatus qv_world_builder_new(QvWorldBuilder **out);

/* Frees a builder that was not built. NULL is ignored. */
void qv_world_builder_free(QvWorldBuilder *builder);

/* Adds an indexed triangle mesh as a geometry, its buffers read as qv_bvh_build_indexed
 * reads them (copied during the call). *geometry_id is its id: 0, 1, 2, ... in the order
 * added. Errors: as qv_bvh_build_indexed; a refused mesh adds nothing. */
QvStatus qv_world_builder_add_mesh(QvWorldBuilder *builder, const float *vertices,
                                   size_t vertex_count, size_t vertex_stride_bytes,
                                   const uint32_t *indices, size_t triangle_count,
                                   size_t index_stride_bytes, uint32_t *geometry_id);

/* Adds a deforming indexed triangle mesh as a geometry: step_count (at least 2) time steps
 * of the same triangles, step j at shutter time j / (step_count - 1). `vertices` holds
 * step_count * vertex_count positions, step j's vertex i at position j * vertex_count + i
 * (each vertex_stride_bytes after the last); `indices` the triangle_count triangles every
 * step shares (indices below vertex_count). Buffers read as qv_bvh_build_indexed reads them
 * (copied during the call). A ray at time t meets the triangles interpolated linearly to t
 * between the two steps around it. *geometry_id is its id, as qv_world_builder_add_mesh's.
 * Errors: as qv_bvh_build_indexed; QV_INVALID_ARGUMENT for step_count below 2, a vertex
 * count times step_count that overflows, or more than 65536 steps of no vertices; a refused
 * mesh adds nothing. */
QvStatus qv_world_builder_add_moving_mesh(QvWorldBuilder *builder, const float *vertices,
                                          size_t vertex_count, size_t vertex_stride_bytes,
                                          size_t step_count, const uint32_t *indices,
                                          size_t triangle_count, size_t index_stride_bytes,
                                          uint32_t *geometry_id);

/* Places geometry `geometry` in the world by `transform`, object to world: 12 floats, a
 * row-major 3x4 matrix (row r is transform[4r .. 4r+3], the last column the translation;
 * the identity is {1,0,0,0, 0,1,0,0, 0,0,1,0}). The instance is seen by rays whose mask
 * shares a bit with `mask` (0xFFFFFFFF: every ray). *instance_id is its id: 0, 1, 2, ... in
 * the order added.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT for a geometry not added or a transform that
 * is not finite or not invertible in float precision; a refused instance adds nothing. */
QvStatus qv_world_builder_add_instance(QvWorldBuilder *builder, uint32_t geometry,
                                       const float transform[12], uint32_t mask,
                                       uint32_t *instance_id);

/* Places geometry `geometry` moving over the shutter through key_count transforms (keys:
 * 12 * key_count floats, each key read as qv_world_builder_add_instance reads its transform),
 * evenly spaced from time 0 to 1: a ray at QvRay.time meets it where the keys place it then,
 * interpolated linearly (interpolation 0) or decomposed (1: rotation, scale and translation
 * apart, rotations turning at a constant speed, so a spinning wheel keeps its size). Seen by
 * rays whose mask shares a bit with `mask`; *instance_id is its id.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT for a geometry not added, fewer than 2 or more
 * than 256 keys, a key that is not finite or not invertible, keys that mirror beside keys that
 * do not, a decomposed step of half a turn or more, or another interpolation; a refused
 * instance adds nothing. */
QvStatus qv_world_builder_add_moving_instance(QvWorldBuilder *builder, uint32_t geometry,
                                              const float *keys, uint32_t key_count,
                                              uint32_t interpolation, uint32_t mask,
                                              uint32_t *instance_id);

/* Gives geometry `geometry` a filter (see QvFilterFn for the contract): every candidate hit
 * of the geometry, in any instance, is kept only when filter(user, &candidate) returns
 * nonzero. The candidate's t, u, v, prim, geometry and instance are those the hit would
 * have. Replaces the geometry's earlier filter. A geometry with a filter is traced ray by
 * ray, not in packets.
 * Errors: QV_NULL_POINTER (builder or filter); QV_INVALID_ARGUMENT for a geometry not
 * added. */
QvStatus qv_world_builder_set_filter(QvWorldBuilder *builder, uint32_t geometry,
                                     QvFilterFn filter, void *user);

/* Gives geometry `geometry` its own build options (*options, read during the call, as
 * qv_bvh_build_indexed_with reads them), used for it rather than those given to
 * qv_world_build_with. Replaces the geometry's earlier options. A moving mesh takes no
 * preset or layout of its own: its steps are built as qv_world_builder_add_moving_mesh
 * builds them.
 * Errors: QV_NULL_POINTER (builder or options: here options may not be NULL);
 * QV_INVALID_ARGUMENT for a geometry not added, or options refused as
 * qv_bvh_build_indexed_with refuses them. */
QvStatus qv_world_builder_set_options(QvWorldBuilder *builder, uint32_t geometry,
                                      const QvBuildOptions *options);

/* Builds the world: every geometry's BVH and the top level over the instances, in parallel.
 * Consumes the builder whatever the outcome (do not use or free it again), except when
 * `builder` or `out` is NULL (QV_NULL_POINTER: nothing is consumed). On QV_OK *out is the
 * world: free it with qv_world_free; on failure NULL. An empty world is not an error.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT (too many instances or geometries). */
QvStatus qv_world_build(QvWorldBuilder *builder, QvWorld **out);

/* As qv_world_build (which is this with options NULL), with *options (NULL: the defaults)
 * for the top level and for every geometry without options of its own
 * (qv_world_builder_set_options). The same rule for the builder: consumed whatever the
 * outcome, refused options included, except when `builder` or `out` is NULL.
 * Errors: as qv_world_build; QV_INVALID_ARGUMENT for options refused as
 * qv_bvh_build_indexed_with refuses them. */
QvStatus qv_world_build_with(QvWorldBuilder *builder, const QvBuildOptions *options,
                             QvWorld **out);

/* Frees a world. NULL is ignored. The world must not be in use on another thread. */
void qv_world_free(QvWorld *world);

/* The point of the world's triangles nearest point[0..3] within max_distance (inclusive;
 * INFINITY for any distance), measured in world space through every instance transform
 * (non-uniform scales and shears included), into *hit: the miss record when none lies that
 * near, and for a non-finite point or a NaN or negative max_distance. Instance masks and
 * filters do not apply. A moving instance is measured where it is at time 0 (its first key):
 * qv_world_closest_point_at with time 0. Errors: QV_NULL_POINTER. */
QvStatus qv_world_closest_point(const QvWorld *world, const float point[3], float max_distance,
                                QvPointHit *hit);

/* As qv_world_closest_point, with each moving instance measured where its keys place it at
 * shutter time `time`, taken as QvRay.time is (clamped into [0, 1], NaN as 0): the answer of
 * the world with every instance placed at that time. Errors: QV_NULL_POINTER. */
QvStatus qv_world_closest_point_at(const QvWorld *world, const float point[3],
                                   float max_distance, float time, QvPointHit *hit);

/* Writes the world to the file `path` (a NUL-terminated file name, created or replaced all or
 * nothing: written beside it as a temporary file, then renamed over it, so a failed save
 * leaves an existing file as it was) in quiver's world file format (docs/file-format.md):
 * every geometry with its BVH, every instance (removed ones too, so ids stay). Filters are code and are not saved: a loaded
 * world has none.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT (a path that names no file, such as "/");
 * QV_IO (the message names the path and the OS error). */
QvStatus qv_world_save(const QvWorld *world, const char *path);

/* Reads a world qv_world_save wrote from the file `path`, checked completely (checksum,
 * every geometry's BVH, every instance's geometry and transform), and builds its top level
 * again. On QV_OK *out is the new world (free it with qv_world_free), with no filters; it
 * answers every query as the saved one did. On failure *out is NULL (when `out` is not NULL).
 * Errors: QV_NULL_POINTER; QV_IO; QV_BAD_FILE (not a saved world, damaged, another format
 * version or byte order, an instance that places nothing: the message says which). */
QvStatus qv_world_load(const char *path, QvWorld **out);

/* The bytes the world holds into *bytes: the top level, every geometry's BVH and triangles
 * once (however many instances place it), the instance records and the motions' keys. Not
 * counted: the copies of the mesh index buffers kept for qv_world_refit_mesh (12 bytes a
 * triangle), filters, and the handle itself. Errors: QV_NULL_POINTER. */
QvStatus qv_world_footprint(const QvWorld *world, size_t *bytes);

/* The closest hit of *ray among the instances its mask sees, into *hit (the miss record
 * when nothing is hit). Errors: QV_NULL_POINTER. */
QvStatus qv_world_closest_hit(const QvWorld *world, const QvRay *ray, QvHit *hit);

/* Whether anything *ray's mask sees is hit within its interval: *occluded is 1 or 0.
 * Errors: QV_NULL_POINTER. */
QvStatus qv_world_any_hit(const QvWorld *world, const QvRay *ray, int *occluded);

/* The closest hits of rays[0..n] into hits[0..n], traced in parallel; each exactly
 * qv_world_closest_hit's. The arrays must not overlap; both may be NULL when n is 0.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT when n elements overflow the address space. */
QvStatus qv_world_closest_hits(const QvWorld *world, const QvRay *rays, size_t n,
                               QvHit *hits);

/* Whether each of rays[0..n] hits anything: occluded[i] is 1 or 0; traced in parallel.
 * Errors: as qv_world_closest_hits. */
QvStatus qv_world_any_hits(const QvWorld *world, const QvRay *rays, size_t n,
                           uint8_t *occluded);

/* The edits below change the world: no other call on it may run meanwhile. Each is one
 * edit, committed before it returns (the top level refit, or rebuilt after an added
 * instance); a refused edit changes nothing. Instance ids stay stable. */

/* Places instance `instance` by `transform` (read as qv_world_builder_add_instance reads
 * it). Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT for an instance that does not exist or
 * was removed, or a transform that is not finite or not invertible. */
QvStatus qv_world_set_transform(QvWorld *world, uint32_t instance, const float transform[12]);

/* Moves instance `instance` from now on through key_count keys (12 * key_count floats,
 * interpolation 0 linear or 1 decomposed: read as qv_world_builder_add_moving_instance reads
 * them); rays at QvRay.time and qv_world_closest_point_at meet it where the keys place it
 * then. qv_world_set_transform makes it stand still again.
 * Errors: QV_NULL_POINTER (world, or keys when key_count is not 0); QV_INVALID_ARGUMENT for
 * an instance that does not exist or was removed, fewer than 2 or more than 256 keys, a key
 * that is not finite or not invertible, keys that mirror beside keys that do not, a
 * decomposed step of half a turn or more, or another interpolation. */
QvStatus qv_world_set_motion(QvWorld *world, uint32_t instance, const float *keys,
                             uint32_t key_count, uint32_t interpolation);

/* Shows instance `instance` only to rays whose mask shares a bit with `mask`.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT for an instance that does not exist or was
 * removed. */
QvStatus qv_world_set_mask(QvWorld *world, uint32_t instance, uint32_t mask);

/* Removes instance `instance`: no ray meets it from now on; its id is never given again.
 * Errors: QV_NULL_POINTER; QV_INVALID_ARGUMENT for an instance that does not exist or was
 * removed before. */
QvStatus qv_world_remove_instance(QvWorld *world, uint32_t instance);

/* Adds an instance of geometry `geometry` (arguments as qv_world_builder_add_instance);
 * *instance_id is its id, one past every id given before (removed ones included).
 * Errors: as qv_world_builder_add_instance. */
QvStatus qv_world_add_instance(QvWorld *world, uint32_t geometry, const float transform[12],
                               uint32_t mask, uint32_t *instance_id);

/* Adds an indexed triangle mesh as a new geometry (buffers read as
 * qv_world_builder_add_mesh reads them, copied during the call), its BVH built now with
 * *options (NULL: the defaults; see QvBuildOptions). *geometry_id is its id, one past the
 * last geometry's. No instance places it yet: add one with qv_world_add_instance.
 * Errors: as qv_bvh_build_indexed_with; a refused mesh adds nothing. */
QvStatus qv_world_add_mesh(QvWorld *world, const float *vertices, size_t vertex_count,
                           size_t vertex_stride_bytes, const uint32_t *indices,
                           size_t triangle_count, size_t index_stride_bytes,
                           const QvBuildOptions *options, uint32_t *geometry_id);

/* Refits mesh geometry `geometry` to new vertex positions for the same triangles (the index
 * buffer it was added with, kept since; vertices read as qv_world_builder_add_mesh reads
 * them; vertex_count may differ from the mesh's as long as every index names one): its
 * tree stays, its boxes follow the vertices, and every instance placing it follows.
 * Everything is checked before anything changes, so a refused refit changes nothing.
 * Errors: QV_NULL_POINTER; QV_BAD_MESH (stride, an index past the new vertices, a
 * non-finite coordinate); QV_INVALID_ARGUMENT for a geometry that does not exist, a moving
 * mesh (qv_world_builder_add_moving_mesh), a geometry of a world from qv_world_load (it
 * keeps no index buffers), or an overflowing size. */
QvStatus qv_world_refit_mesh(QvWorld *world, uint32_t geometry, const float *vertices,
                             size_t vertex_count, size_t vertex_stride_bytes);

#ifdef __cplusplus
}
#endif

#endif /* QUIVER_H */
