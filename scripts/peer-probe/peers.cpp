// Times tinybvh (newest header) BVH8_CPU and Embree 3 rtcIntersect1/rtcOccluded1 on the rays
// the probe dumped: peers SCENE.bin RAYS.bin REPS
#define TINYBVH_IMPLEMENTATION
#include "tiny_bvh.h"
#include <embree3/rtcore.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <vector>
#include <limits>
static std::vector<char> slurp(const char* p) { FILE* f = fopen(p, "rb"); std::vector<char> b; fseek(f, 0, SEEK_END); b.resize(ftell(f)); fseek(f, 0, SEEK_SET); fread(b.data(), 1, b.size(), f); fclose(f); return b; }
struct R { float o[3], d[3], tmin, tmax; };
int main(int argc, char** argv) {
    auto sb = slurp(argv[1]); auto rb = slurp(argv[2]); int reps = atoi(argv[3]);
    uint32_t n; memcpy(&n, sb.data(), 4); const float* tri = (const float*)(sb.data() + 56);
    std::vector<tinybvh::bvhvec4> v(3 * (size_t)n);
    for (size_t i = 0; i < 3 * (size_t)n; i++) v[i] = tinybvh::bvhvec4(tri[3 * i], tri[3 * i + 1], tri[3 * i + 2], 0);
    uint32_t cnt[3]; memcpy(cnt, rb.data(), 12); const R* rays = (const R*)(rb.data() + 12);
    const R* sets[3] = {rays, rays + cnt[0], rays + cnt[0] + cnt[1]};
    tinybvh::BVH8_CPU t8; t8.Build(v.data(), n);
    RTCDevice dev = rtcNewDevice(getenv("QUIVER_EMBREE_CONFIG"));
    RTCScene sc = rtcNewScene(dev);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float* vb = (float*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 3 * (size_t)n);
    unsigned* ib = (unsigned*)rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, n);
    memcpy(vb, tri, 36 * (size_t)n); for (unsigned i = 0; i < 3 * n; i++) ib[i] = i;
    rtcCommitGeometry(g); rtcAttachGeometry(sc, g); rtcReleaseGeometry(g); rtcCommitScene(sc);
    const char* names[3] = {"eye", "shadow", "diffuse"};
    std::vector<double> tt[3], te[3]; size_t sink = 0;
    for (int rep = 0; rep < reps; rep++) for (int k = 0; k < 3; k++) {
        const R* s = sets[k]; uint32_t m = cnt[k]; bool any = k == 1;
        auto a = std::chrono::steady_clock::now();
        for (uint32_t i = 0; i < m; i++) {
            tinybvh::Ray r(tinybvh::bvhvec3(s[i].o[0], s[i].o[1], s[i].o[2]), tinybvh::bvhvec3(s[i].d[0], s[i].d[1], s[i].d[2]), s[i].tmax);
            if (any) sink += t8.IsOccluded(r); else { t8.Intersect(r); sink += r.hit.t < s[i].tmax; }
        }
        auto b = std::chrono::steady_clock::now();
        RTCIntersectContext ctx; rtcInitIntersectContext(&ctx);
        for (uint32_t i = 0; i < m; i++) {
            RTCRayHit rh; RTCRay& r = rh.ray;
            r.org_x = s[i].o[0]; r.org_y = s[i].o[1]; r.org_z = s[i].o[2]; r.dir_x = s[i].d[0]; r.dir_y = s[i].d[1]; r.dir_z = s[i].d[2];
            r.tnear = s[i].tmin; r.tfar = s[i].tmax; r.mask = 0xFFFFFFFF; r.flags = 0; r.time = 0;
            if (any) { rtcOccluded1(sc, &ctx, &r); sink += r.tfar < 0; }
            else { rh.hit.geomID = RTC_INVALID_GEOMETRY_ID; rtcIntersect1(sc, &ctx, &rh); sink += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID; }
        }
        auto c = std::chrono::steady_clock::now();
        tt[k].push_back(m / std::chrono::duration<double>(b - a).count() / 1e6);
        te[k].push_back(m / std::chrono::duration<double>(c - b).count() / 1e6);
    }
    printf("peers %s tinybvh %d.%d.%d:", argv[1], TINY_BVH_VERSION_MAJOR, TINY_BVH_VERSION_MINOR, TINY_BVH_VERSION_SUB);
    for (int k = 0; k < 3; k++) { std::sort(tt[k].begin(), tt[k].end()); std::sort(te[k].begin(), te[k].end());
        printf(" %s t8=%.2f embree=%.2f", names[k], tt[k][reps / 2], te[k][reps / 2]); }
    printf(" (%zu)\n", sink);
}
