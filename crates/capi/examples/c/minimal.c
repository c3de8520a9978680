/*
 * quiver from C: a two-triangle mesh as a BVH and as a world of two instances; rays traced
 * one at a time and as arrays; the world edited, one instance set moving, and its closest
 * points asked at shutter times; the answers printed and checked.
 *
 * Build (from the repository root):
 *   cargo build --release -p quiver-capi
 *   cc crates/capi/examples/c/minimal.c -Icrates/capi/include \
 *      target/release/libquiver_capi.a -lpthread -ldl -lm -o minimal
 *   ./minimal
 *
 * Returns 0 when every answer is the expected one, 1 otherwise. Each traced ray prints one
 * line, its scene ("bvh", "world", "edited", "moving"), the ray, then the hit (or "miss");
 * each closest point a line "point", its scene, the query, then the answer; which
 * crates/capi/tests/c_example.rs compares with what the Rust API answers for the same rays
 * and points.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "quiver.h"

static int failures = 0;

/* Counts a failed check and says which. */
static void check(int ok, const char *what) {
    if (!ok) {
        fprintf(stderr, "wrong: %s\n", what);
        failures++;
    }
}

/* Stops on a refused call, printing quiver's message. */
static int ok(QvStatus s, const char *call) {
    if (s != QV_OK) {
        fprintf(stderr, "%s failed (%d): %s\n", call, (int)s, qv_last_error());
        failures++;
        return 0;
    }
    return 1;
}

/* A ray straight down (-z) from height 5 above (x, y), seen by `mask`. */
static QvRay down(float x, float y, uint32_t mask) {
    QvRay r = {{x, y, 5.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, mask};
    return r;
}

static void print_hit(const char *what, const QvRay *r, const QvHit *h) {
    printf("%s %.9g %.9g %.9g %.9g %.9g %.9g %u %.9g -> ", what, r->org[0], r->org[1],
           r->org[2], r->dir[0], r->dir[1], r->dir[2], r->mask, r->time);
    if (h->prim == QV_INVALID_ID) {
        printf("miss\n");
    } else {
        printf("prim %u geometry %u instance %u t %.9g u %.9g v %.9g\n", h->prim, h->geometry,
               h->instance, h->t, h->u, h->v);
    }
}

static void print_point(const char *what, const float p[3], float max_distance, float time,
                        const QvPointHit *h) {
    printf("point %s %.9g %.9g %.9g %.9g %.9g -> ", what, p[0], p[1], p[2], max_distance, time);
    if (h->prim == QV_INVALID_ID) {
        printf("miss\n");
    } else {
        printf("prim %u geometry %u instance %u point %.9g %.9g %.9g u %.9g v %.9g distance "
               "%.9g\n",
               h->prim, h->geometry, h->instance, h->point[0], h->point[1], h->point[2], h->u,
               h->v, h->distance);
    }
}

int main(void) {
    /* The struct sizes, which the Rust test compares with the library's own. */
    printf("sizes QvRay %zu QvHit %zu QvPointHit %zu QvBuildOptions %zu\n", sizeof(QvRay),
           sizeof(QvHit), sizeof(QvPointHit), sizeof(QvBuildOptions));

    /* A unit square in the z = 0 plane: four vertices, two triangles. */
    const float vertices[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    const uint32_t indices[2][3] = {{0, 1, 2}, {0, 2, 3}};

    /* ---- One BVH ---- */
    QvBvh *bvh = NULL;
    if (!ok(qv_bvh_build_indexed(&vertices[0][0], 4, sizeof vertices[0], &indices[0][0], 2,
                                 sizeof indices[0], &bvh),
            "qv_bvh_build_indexed"))
        return 1;

    QvRay rays[3] = {down(0.25f, 0.75f, ~0u), down(0.75f, 0.25f, ~0u), down(2.5f, 0.5f, ~0u)};
    const uint32_t bvh_prim[3] = {1, 0, QV_INVALID_ID};
    QvHit hits[3];
    for (int i = 0; i < 3; i++) {
        ok(qv_bvh_closest_hit(bvh, &rays[i], &hits[i]), "qv_bvh_closest_hit");
        print_hit("bvh", &rays[i], &hits[i]);
        check(hits[i].prim == bvh_prim[i], "bvh: the triangle hit");
        check(hits[i].prim == QV_INVALID_ID || hits[i].t == 5.0f, "bvh: t = 5");
    }
    QvHit array_hits[3];
    uint8_t occluded[3];
    ok(qv_bvh_closest_hits(bvh, rays, 3, array_hits), "qv_bvh_closest_hits");
    ok(qv_bvh_any_hits(bvh, rays, 3, occluded), "qv_bvh_any_hits");
    for (int i = 0; i < 3; i++) {
        check(memcmp(&array_hits[i], &hits[i], sizeof(QvHit)) == 0, "bvh: array = single");
        check(occluded[i] == (hits[i].prim != QV_INVALID_ID), "bvh: any hit");
    }

    /* A refused call says why. */
    uint32_t bad_indices[3] = {0, 1, 7};
    QvBvh *bad = NULL;
    QvStatus s = qv_bvh_build_indexed(&vertices[0][0], 4, 12, bad_indices, 1, 12, &bad);
    check(s == QV_BAD_MESH && bad == NULL, "a bad index is QV_BAD_MESH");
    printf("refused: %s\n", qv_last_error());

    /* The same mesh built fast into 4-wide quantized nodes: the same hits, its own size. */
    const QvBuildOptions quant_options = {QV_QUALITY_FAST, "bvh4-quant"};
    QvBvh *quant = NULL;
    size_t bytes = 0, quant_bytes = 0;
    if (ok(qv_bvh_build_indexed_with(&vertices[0][0], 4, 12, &indices[0][0], 2, 12,
                                     &quant_options, &quant),
           "qv_bvh_build_indexed_with")) {
        for (int i = 0; i < 3; i++) {
            QvHit h;
            ok(qv_bvh_closest_hit(quant, &rays[i], &h), "qv_bvh_closest_hit");
            check(memcmp(&h, &hits[i], sizeof(QvHit)) == 0, "bvh4-quant: the same hit");
        }
        ok(qv_bvh_footprint(bvh, &bytes), "qv_bvh_footprint");
        ok(qv_bvh_footprint(quant, &quant_bytes), "qv_bvh_footprint");
        check(bytes > 0 && quant_bytes > 0, "footprints");
        printf("footprint bvh8-dfs %zu bvh4-quant %zu\n", bytes, quant_bytes);
    }
    qv_bvh_free(quant);
    qv_bvh_free(bvh);

    /* ---- A world: the square twice, the second moved by (2, 0, -1) and seen by mask 2 ---- */
    QvWorldBuilder *builder = NULL;
    uint32_t square, near, far;
    const float identity[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    const float moved[12] = {1, 0, 0, 2, 0, 1, 0, 0, 0, 0, 1, -1};
    if (!ok(qv_world_builder_new(&builder), "qv_world_builder_new") ||
        !ok(qv_world_builder_add_mesh(builder, &vertices[0][0], 4, 12, &indices[0][0], 2, 12,
                                      &square),
            "qv_world_builder_add_mesh") ||
        !ok(qv_world_builder_add_instance(builder, square, identity, 1, &near),
            "qv_world_builder_add_instance") ||
        !ok(qv_world_builder_add_instance(builder, square, moved, 2, &far),
            "qv_world_builder_add_instance")) {
        qv_world_builder_free(builder);
        return 1;
    }
    QvWorld *world = NULL;
    if (!ok(qv_world_build(builder, &world), "qv_world_build"))
        return 1;

    QvRay wrays[4] = {down(0.25f, 0.75f, ~0u), down(2.5f, 0.25f, ~0u), down(2.5f, 0.25f, 1),
                      down(5.0f, 5.0f, ~0u)};
    const uint32_t want_instance[4] = {near, far, QV_INVALID_ID, QV_INVALID_ID};
    const float want_t[4] = {5.0f, 6.0f, INFINITY, INFINITY};
    QvHit whits[4];
    ok(qv_world_closest_hits(world, wrays, 4, whits), "qv_world_closest_hits");
    for (int i = 0; i < 4; i++) {
        QvHit one;
        ok(qv_world_closest_hit(world, &wrays[i], &one), "qv_world_closest_hit");
        print_hit("world", &wrays[i], &one);
        check(memcmp(&one, &whits[i], sizeof(QvHit)) == 0, "world: array = single");
        check(one.instance == want_instance[i], "world: the instance hit");
        check(one.t == want_t[i], "world: t");
        int occ = -1;
        ok(qv_world_any_hit(world, &wrays[i], &occ), "qv_world_any_hit");
        check(occ == (want_instance[i] != QV_INVALID_ID), "world: any hit");
    }

    /* An edit: the second square brought up to z = 0 and shown to every ray. */
    const float lifted[12] = {1, 0, 0, 2, 0, 1, 0, 0, 0, 0, 1, 0};
    ok(qv_world_set_transform(world, far, lifted), "qv_world_set_transform");
    ok(qv_world_set_mask(world, far, ~0u), "qv_world_set_mask");
    QvHit edited;
    ok(qv_world_closest_hit(world, &wrays[2], &edited), "qv_world_closest_hit");
    print_hit("edited", &wrays[2], &edited);
    check(edited.instance == far && edited.t == 5.0f, "world: the edit moved the instance");

    /* Motion: the first square set rising from z = 0 to z = 4 over the shutter (two keys,
     * linear), met where the keys place it at a ray's time and at a closest point's. */
    const float rise[24] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
                            1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 4};
    ok(qv_world_set_motion(world, near, rise, 2, 0), "qv_world_set_motion");
    QvRay late = down(0.25f, 0.25f, ~0u);
    late.time = 0.5f;
    QvHit risen;
    ok(qv_world_closest_hit(world, &late, &risen), "qv_world_closest_hit");
    print_hit("moving", &late, &risen);
    check(risen.instance == near && risen.t == 3.0f, "moving: met at z = 2 half way");
    const float above[3] = {0.25f, 0.25f, 3.0f};
    const float times[4] = {0.0f, 0.5f, 1.0f, 2.0f}; /* 2: past the shutter, its end */
    const float want_z[4] = {0.0f, 2.0f, 4.0f, 4.0f};
    QvPointHit nearest[4];
    for (int i = 0; i < 4; i++) {
        ok(qv_world_closest_point_at(world, above, INFINITY, times[i], &nearest[i]),
           "qv_world_closest_point_at");
        print_point("moving", above, INFINITY, times[i], &nearest[i]);
        check(nearest[i].instance == near && nearest[i].point[2] == want_z[i] &&
                  nearest[i].distance == fabsf(3.0f - want_z[i]),
              "moving: the closest point where the keys place the square");
    }
    QvPointHit at_zero;
    ok(qv_world_closest_point(world, above, INFINITY, &at_zero), "qv_world_closest_point");
    print_point("moving", above, INFINITY, 0.0f, &at_zero);
    check(memcmp(&at_zero, &nearest[0], sizeof(QvPointHit)) == 0,
          "moving: qv_world_closest_point is time 0");
    /* A refused motion says why and changes nothing. */
    s = qv_world_set_motion(world, 7, rise, 2, 0);
    check(s == QV_INVALID_ARGUMENT, "a motion of no instance is QV_INVALID_ARGUMENT");
    printf("refused: %s\n", qv_last_error());

    qv_world_free(world);
    if (failures == 0)
        printf("all answers as expected\n");
    return failures == 0 ? 0 : 1;
}
