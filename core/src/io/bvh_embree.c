/* io/bvh_embree.c: everything that touches Embree.
 *
 * Design: each scene owns one RTCDevice and one committed RTCScene holding a
 * single triangle geometry (and, with emitters, a second scene of the
 * emissive triangles alone, see build_emitters) whose vertex and index buffers are shared with the
 * gi_scene arrays (scene.c pads the vertex array by 16 bytes, which Embree
 * reads past the last vertex). Devices are per scene so the "threads=N"
 * option applies per scene and nothing is global. After the commit the
 * Embree scene is read-only, so the queries here are thread-safe. Shadow rays
 * go out as streams (rtcOccluded1M) in fixed chunks on the stack; box
 * queries use rtcPointQuery with the sphere around the box, so only BVH
 * nodes near the box are visited, and a callback keeps each triangle whose
 * bounding box overlaps the box. The build uses medium quality (no spatial
 * splits), so every triangle sits in exactly one leaf and a point query
 * visits it at most once. An empty scene (rtc == NULL) is handled in every
 * entry point. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "scene/scene_internal.h"

/* Embree reports errors through the device; we read them back with
 * rtcGetDeviceError right after each step, so the callback keeps nothing. */
static void on_embree_error(void *user, enum RTCError code, const char *str) {
  (void)user;
  (void)code;
  (void)str;
}

static const char *rtc_error_text(enum RTCError e) {
  switch (e) {
    case RTC_ERROR_NONE: return "no error";
    case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
    case RTC_ERROR_CANCELLED: return "cancelled";
    default: return "unknown error";
  }
}

/* A second scene over the emissive triangles alone, sharing the vertices:
 * a ray looking for an emitter (the MIS companions of light sampling)
 * asks it first and pays a full-scene shadow ray only when it meets one;
 * in a closed room most such rays meet a wall and never an emitter. */
static enum RTCError build_emitters(struct gi_scene *s) {
  s->rtc_emit = rtcNewScene(s->device);
  rtcSetSceneFlags(s->rtc_emit, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(s->rtc_emit, RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry g = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, s->vertices, 0,
                             3 * sizeof(float), s->num_vertices);
  uint32_t *ix = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t),
                                         s->num_emitters);
  if (!ix) {
    rtcReleaseGeometry(g);
    enum RTCError e = rtcGetDeviceError(s->device);
    return e != RTC_ERROR_NONE ? e : RTC_ERROR_OUT_OF_MEMORY;
  }
  for (uint32_t q = 0; q < s->num_emitters; q++)
    memcpy(&ix[3 * (size_t)q], &s->indices[3 * (size_t)s->emitter_tri[q]], 3 * sizeof(uint32_t));
  rtcCommitGeometry(g);
  rtcAttachGeometryByID(s->rtc_emit, g, 0);
  rtcReleaseGeometry(g);
  rtcCommitScene(s->rtc_emit);
  return rtcGetDeviceError(s->device);
}

gi_result gi__bvh_build(struct gi_scene *s, int threads, gi_error_info *err) {
  char config[64] = "";
  if (threads > 0) snprintf(config, sizeof config, "threads=%d", threads);
  s->device = rtcNewDevice(config[0] ? config : NULL);
  if (!s->device)
    return gi__fail(err, GI_ERR_BACKEND, "scene '%s': Embree device creation failed: %s", s->name,
                    rtc_error_text(rtcGetDeviceError(NULL)));
  rtcSetDeviceErrorFunction(s->device, on_embree_error, NULL);

  s->rtc = rtcNewScene(s->device);
  /* ROBUST: shadow rays that graze shared edges must not leak through cracks. */
  rtcSetSceneFlags(s->rtc, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(s->rtc, RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry g = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_MEDIUM);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, s->vertices, 0,
                             3 * sizeof(float), s->num_vertices);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, s->indices, 0,
                             3 * sizeof(uint32_t), s->num_triangles);
  rtcCommitGeometry(g);
  rtcAttachGeometryByID(s->rtc, g, 0);
  rtcReleaseGeometry(g);
  rtcCommitScene(s->rtc);
  enum RTCError e = rtcGetDeviceError(s->device);
  if (e == RTC_ERROR_NONE && s->num_emitters > 0) e = build_emitters(s);
  if (e != RTC_ERROR_NONE) {
    gi__bvh_free(s);
    return gi__fail(err, e == RTC_ERROR_OUT_OF_MEMORY ? GI_ERR_NOMEM : GI_ERR_BACKEND,
                    "scene '%s': Embree BVH build over %u triangles failed: %s", s->name, s->num_triangles,
                    rtc_error_text(e));
  }
  return GI_OK;
}

void gi__bvh_free(struct gi_scene *s) {
  if (s->rtc_emit) rtcReleaseScene(s->rtc_emit);
  if (s->rtc) rtcReleaseScene(s->rtc);
  if (s->device) rtcReleaseDevice(s->device);
  s->rtc_emit = NULL;
  s->rtc = NULL;
  s->device = NULL;
}

enum { CHUNK = 256 };

/* Embree asserts (and aborts the process) on a ray whose origin or
 * direction has a coordinate beyond about 1.8e18 (its ray.valid()): such a
 * ray is no ray here. The callers' own limits (points within 1e9 of the
 * scene) stop them well before; this keeps a missed check from killing a
 * server. */
#define RAY_LARGE 1e18f
static inline int ray_ok(const float org[3], const float dir[3]) {
  for (int k = 0; k < 3; k++)
    if (!(fabsf(org[k]) <= RAY_LARGE) || !(fabsf(dir[k]) <= RAY_LARGE)) return 0;
  return 1;
}

void gi__occluded(const struct gi_scene *s, int n, const float *org, const float *dir,
                  const float *tnear, const float *tfar, uint8_t *visible) {
  if (!s->rtc) {
    if (n > 0) memset(visible, 1, (size_t)n);
    return;
  }
  struct RTCRay rays[CHUNK];
  for (int base = 0; base < n; base += CHUNK) {
    int m = n - base < CHUNK ? n - base : CHUNK;
    for (int i = 0; i < m; i++) {
      size_t r = (size_t)(base + i);
      struct RTCRay *ray = &rays[i];
      ray->org_x = org[3 * r];
      ray->org_y = org[3 * r + 1];
      ray->org_z = org[3 * r + 2];
      ray->dir_x = dir[3 * r];
      ray->dir_y = dir[3 * r + 1];
      ray->dir_z = dir[3 * r + 2];
      ray->tnear = tnear[r];
      ray->tfar = tfar[r];
      ray->time = 0.f;
      ray->mask = UINT32_MAX;
      ray->id = (unsigned)i;
      ray->flags = 0;
      /* A segment that is empty or not finite blocks nothing: Embree skips
       * rays with tfar < tnear, so disable it that way. */
      int ok = ray_ok(&org[3 * r], &dir[3 * r]) && isfinite(tnear[r]) && !isnan(tfar[r]) && tnear[r] >= 0.f &&
               tnear[r] <= tfar[r];
      if (!ok) {
        ray->org_x = ray->org_y = ray->org_z = ray->dir_x = ray->dir_y = 0.f;
        ray->dir_z = 1.f;
        ray->tnear = 0.f;
        ray->tfar = -1.f;
      }
    }
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    if (m == 1) rtcOccluded1(s->rtc, &ctx, &rays[0]);
    else rtcOccluded1M(s->rtc, &ctx, rays, (unsigned)m, sizeof(struct RTCRay));
    /* Embree sets tfar to -inf on a hit; disabled rays keep tfar = -1. */
    for (int i = 0; i < m; i++) visible[base + i] = !(rays[i].tfar == -INFINITY);
  }
}

/* The nearest hit in scene sc along org + t dir, t in [tnear, tfar]: 1
 * with its distance and primitive, 0 when none or the ray is not finite. */
static int closest_hit(RTCScene sc, const float org[3], const float dir[3], float tnear, float tfar, float *t,
                       uint32_t *prim) {
  if (!sc) return 0;
  if (!ray_ok(org, dir) || !isfinite(tnear) || isnan(tfar) || tnear < 0.f || tnear > tfar) return 0;
  struct RTCRayHit rh;
  memset(&rh, 0, sizeof rh);
  rh.ray.org_x = org[0]; rh.ray.org_y = org[1]; rh.ray.org_z = org[2];
  rh.ray.dir_x = dir[0]; rh.ray.dir_y = dir[1]; rh.ray.dir_z = dir[2];
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.mask = UINT32_MAX;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  rtcIntersect1(sc, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return 0;
  *t = rh.ray.tfar;
  *prim = rh.hit.primID;
  return 1;
}

int gi__intersect1(const struct gi_scene *s, const float org[3], const float dir[3],
                   float tnear, float tfar, float *t, uint32_t *tri, float ng[3]) {
  float th;
  uint32_t p;
  if (!closest_hit(s->rtc, org, dir, tnear, tfar, &th, &p)) return 0;
  if (t) *t = th;
  if (tri) *tri = p;
  if (ng) {
    /* Our own winding normal (v1-v0) x (v2-v0), so the convention does not
     * depend on how Embree orients Ng. */
    const float *a = s->vertices + 3 * (size_t)s->indices[3 * (size_t)p];
    const float *b = s->vertices + 3 * (size_t)s->indices[3 * (size_t)p + 1];
    const float *c = s->vertices + 3 * (size_t)s->indices[3 * (size_t)p + 2];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0)) len = 1;
    for (int k = 0; k < 3; k++) ng[k] = (float)(n[k] / len);
  }
  return 1;
}

/* Within this many float steps of the eye's largest coordinate a hit is
 * on the surface the eye lies on. */
#define EYE_ON_SURFACE_ULPS 4.0f
/* A surface within ~84 degrees of level is a floor (the eye stands on it). */
#define EYE_LEVEL_COS 0.1f

int gi__camera_hit(const struct gi_scene *s, const float eye[3], const float w[3], float *t, uint32_t *tri,
                   float ng[3]) {
  if (!gi__intersect1(s, eye, w, 0, INFINITY, t, tri, ng)) return 0;
  float m = fmaxf(fabsf(eye[0]), fmaxf(fabsf(eye[1]), fabsf(eye[2])));
  float eps = EYE_ON_SURFACE_ULPS * FLT_EPSILON * (1.f + m);
  if (*t > eps) return 1;
  /* The eye's side: above a level surface (rooms are wound either way),
   * else the side it faces. A ray into it sees it; one leaving it, what
   * lies beyond (it met the surface from behind at t = 0: a camera on a
   * floor saw only black, as did the path tracer beside it). */
  const float up[3] = {0, s->up == GI_UP_Z ? 0.f : 1.f, s->up == GI_UP_Z ? 1.f : 0.f};
  float cu = gi__dot(ng, up), side = fabsf(cu) > EYE_LEVEL_COS && cu < 0 ? -1.f : 1.f;
  if (side * gi__dot(ng, w) <= 0) return 1;
  return gi__intersect1(s, eye, w, eps, INFINITY, t, tri, ng);
}

/* n closest-hit queries on the emitters' scene as one stream
 * (rtcIntersect1M): a probe's or a voxel side's hundreds of MIS rays paid
 * Embree's per-call setup one by one. Rays closest_hit would refuse
 * (not finite, empty segment) are disabled the same way gi__occluded
 * disables them and find nothing. */
void gi__emitter_find_n(const struct gi_scene *s, int n, const float (*org)[3], const float (*dir)[3],
                        const float *tnear, float *t, uint32_t *tri, uint8_t *found) {
  if (!s->rtc_emit) {
    if (n > 0) memset(found, 0, (size_t)n);
    return;
  }
  struct RTCRayHit rh[CHUNK];
  for (int base = 0; base < n; base += CHUNK) {
    int m = n - base < CHUNK ? n - base : CHUNK;
    for (int i = 0; i < m; i++) {
      int r = base + i;
      struct RTCRayHit *h = &rh[i];
      memset(h, 0, sizeof *h);
      int ok = ray_ok(org[r], dir[r]) && isfinite(tnear[r]) && tnear[r] >= 0.f;
      h->ray.org_x = ok ? org[r][0] : 0.f, h->ray.org_y = ok ? org[r][1] : 0.f, h->ray.org_z = ok ? org[r][2] : 0.f;
      h->ray.dir_x = ok ? dir[r][0] : 0.f, h->ray.dir_y = ok ? dir[r][1] : 0.f, h->ray.dir_z = ok ? dir[r][2] : 1.f;
      h->ray.tnear = ok ? tnear[r] : 0.f;
      h->ray.tfar = ok ? INFINITY : -1.f;
      h->ray.mask = UINT32_MAX;
      h->ray.id = (unsigned)i;
      h->hit.geomID = RTC_INVALID_GEOMETRY_ID;
      h->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    }
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    if (m == 1) rtcIntersect1(s->rtc_emit, &ctx, &rh[0]);
    else rtcIntersect1M(s->rtc_emit, &ctx, rh, (unsigned)m, sizeof(struct RTCRayHit));
    for (int i = 0; i < m; i++) {
      int r = base + i;
      uint32_t slot = rh[i].hit.primID;
      found[r] = rh[i].hit.geomID != RTC_INVALID_GEOMETRY_ID && slot < s->num_emitters;
      if (!found[r]) continue;
      t[r] = rh[i].ray.tfar;
      tri[r] = s->emitter_tri[slot];
    }
  }
}

/* State of one box query, passed to the point-query callback. */
typedef struct box_query {
  const struct gi_scene *s;
  float lo[3], hi[3];
  uint32_t **out;
  size_t *count, *cap;
  int oom;
} box_query;

static bool box_cb(struct RTCPointQueryFunctionArguments *args) {
  box_query *q = args->userPtr;
  if (q->oom) return false;
  const struct gi_scene *s = q->s;
  uint32_t p = args->primID;
  const uint32_t *ti = s->indices + 3 * (size_t)p;
  for (int k = 0; k < 3; k++) {
    float a = s->vertices[3 * (size_t)ti[0] + k], b = s->vertices[3 * (size_t)ti[1] + k],
          c = s->vertices[3 * (size_t)ti[2] + k];
    /* Inline min/max: fminf and fmaxf are libm calls here (vertices are finite). */
    float mn = a < b ? a : b, mx = a > b ? a : b;
    mn = c < mn ? c : mn, mx = c > mx ? c : mx;
    if (mx < q->lo[k] || mn > q->hi[k]) return false;
  }
  if (*q->count == *q->cap) {
    size_t nc = *q->cap ? 2 * *q->cap : 256;
    uint32_t *n = gi__realloc(*q->out, nc * sizeof *n);
    if (!n) { q->oom = 1; return false; }
    *q->out = n;
    *q->cap = nc;
  }
  (*q->out)[(*q->count)++] = p;
  return false; /* the query radius stays as it is */
}

static int cmp_u32(const void *a, const void *b) {
  uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
  return x < y ? -1 : x > y;
}

/* A large list is ordered through a bitmap over the scene's triangles,
 * linear where qsort took a sixth of a city level's voxelization; without
 * memory for the bitmap, qsort. */
#define ORDER_BITMAP_MIN 4096
void gi__order_tris(const struct gi_scene *s, uint32_t *tris, size_t *count) {
  size_t n = *count;
  uint64_t *bits = n >= ORDER_BITMAP_MIN ? gi__calloc(((size_t)s->num_triangles + 63) / 64, sizeof *bits) : NULL;
  if (bits) {
    for (size_t q = 0; q < n; q++) bits[tris[q] / 64] |= 1ull << (tris[q] % 64);
    size_t m = 0;
    for (size_t w = 0; w < ((size_t)s->num_triangles + 63) / 64; w++)
      for (uint64_t x = bits[w]; x; x &= x - 1) tris[m++] = (uint32_t)(w * 64 + (size_t)__builtin_ctzll(x));
    *count = m;
    gi__free(bits);
    return;
  }
  if (n > 1) qsort(tris, n, sizeof *tris, cmp_u32);
  size_t m = 0;
  for (size_t q = 0; q < n; q++)
    if (m == 0 || tris[q] != tris[m - 1]) tris[m++] = tris[q];
  *count = m;
}

/* One point query: everything within the sphere around [lo, hi], kept
 * where its bounds overlap the box (box_cb). */
static gi_result query_sphere(const struct gi_scene *s, const float lo[3], const float hi[3], uint32_t **out,
                              size_t *count, size_t *cap) {
  box_query q = {.s = s, .out = out, .count = count, .cap = cap};
  memcpy(q.lo, lo, sizeof q.lo);
  memcpy(q.hi, hi, sizeof q.hi);
  struct RTCPointQuery pq;
  double h2 = 0;
  double c[3];
  for (int k = 0; k < 3; k++) {
    c[k] = 0.5 * ((double)lo[k] + (double)hi[k]);
    double h = 0.5 * ((double)hi[k] - (double)lo[k]);
    h2 += h * h;
  }
  pq.x = (float)c[0];
  pq.y = (float)c[1];
  pq.z = (float)c[2];
  pq.time = 0.f;
  /* Circumscribed sphere, widened so float rounding of the centre cannot cut off a corner. */
  double r = sqrt(h2);
  /* A box beyond Embree's ray range (RAY_LARGE) holds none of the scene's triangles. */
  if (!(fabs(c[0]) + r <= RAY_LARGE && fabs(c[1]) + r <= RAY_LARGE && fabs(c[2]) + r <= RAY_LARGE)) return GI_OK;
  pq.radius = (float)(r * (1.0 + 1e-5) + 1e-6 * (fabs(c[0]) + fabs(c[1]) + fabs(c[2])) + 1e-30);
  struct RTCPointQueryContext ctx;
  rtcInitPointQueryContext(&ctx);
  rtcPointQuery(s->rtc, &pq, &ctx, box_cb, &q);
  return q.oom ? GI_ERR_NOMEM : GI_OK;
}

/* The point of triangle abc nearest p, by the Voronoi region of p: a
 * vertex, an edge or the face (the standard barycentric case split). */
static void tri_closest(const float p[3], const float a[3], const float b[3], const float c[3], float out[3]) {
  float ab[3], ac[3], ap[3], bp[3], cp[3];
  for (int k = 0; k < 3; k++)
    ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k], bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
  float d1 = gi__dot(ab, ap), d2 = gi__dot(ac, ap), d3 = gi__dot(ab, bp), d4 = gi__dot(ac, bp);
  float d5 = gi__dot(ab, cp), d6 = gi__dot(ac, cp);
  float u = 0, v = 0; /* out = a + u ab + v ac */
  float va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
  if (d1 <= 0 && d2 <= 0) u = v = 0;
  else if (d3 >= 0 && d4 <= d3) u = 1, v = 0;
  else if (d6 >= 0 && d5 <= d6) u = 0, v = 1;
  else if (vc <= 0 && d1 >= 0 && d3 <= 0) u = d1 / (d1 - d3), v = 0;
  else if (vb <= 0 && d2 >= 0 && d6 <= 0) u = 0, v = d2 / (d2 - d6);
  else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    float w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    u = 1 - w, v = w;
  } else {
    float den = va + vb + vc;
    if (den > 0) u = vb / den, v = vc / den;
  }
  for (int k = 0; k < 3; k++) out[k] = a[k] + u * ab[k] + v * ac[k];
}

typedef struct {
  const struct gi_scene *s;
  float p[3], q[3], d2;
  int found;
  uint32_t tri; /* the triangle q lies on */
} near_query;

static bool near_cb(struct RTCPointQueryFunctionArguments *args) {
  near_query *nq = args->userPtr;
  const struct gi_scene *s = nq->s;
  const uint32_t *ti = s->indices + 3 * (size_t)args->primID;
  float q[3];
  tri_closest(nq->p, &s->vertices[3 * (size_t)ti[0]], &s->vertices[3 * (size_t)ti[1]],
              &s->vertices[3 * (size_t)ti[2]], q);
  float e[3] = {q[0] - nq->p[0], q[1] - nq->p[1], q[2] - nq->p[2]}, d2 = gi__dot(e, e);
  if (!(d2 < nq->d2)) return false;
  nq->d2 = d2, nq->found = 1, nq->tri = args->primID;
  memcpy(nq->q, q, sizeof nq->q);
  args->query->radius = sqrtf(d2); /* nothing farther can win now */
  return true;
}

int gi__closest_point(const struct gi_scene *s, const float p[3], float radius, float q[3], float *dist,
                      float n[3]) {
  if (!s->rtc || !ray_ok(p, p) || !(radius > 0) || !(radius <= RAY_LARGE)) return 0;
  near_query nq = {.s = s, .p = {p[0], p[1], p[2]}, .d2 = radius * radius};
  struct RTCPointQuery pq = {.x = p[0], .y = p[1], .z = p[2], .time = 0.f, .radius = radius};
  struct RTCPointQueryContext ctx;
  rtcInitPointQueryContext(&ctx);
  rtcPointQuery(s->rtc, &pq, &ctx, near_cb, &nq);
  if (!nq.found) return 0;
  memcpy(q, nq.q, sizeof nq.q);
  *dist = sqrtf(nq.d2);
  if (n) {
    const uint32_t *ti = s->indices + 3 * (size_t)nq.tri;
    const float *a = &s->vertices[3 * (size_t)ti[0]], *b = &s->vertices[3 * (size_t)ti[1]],
                *c = &s->vertices[3 * (size_t)ti[2]];
    float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    gi__cross(e1, e2, n);
    float l = gi__len(n);
    for (int k = 0; k < 3; k++) n[k] = l > 0 ? n[k] / l : 0.f;
  }
  return 1;
}

/* A box more than this many times longer than it is thick is queried in
 * nearly cubic parts, at most QUERY_PARTS along a side: one sphere around
 * a moving cascade's scroll slab (32 x 32 x 2 cells of its coarsest level)
 * took in most of the city, 1.9 ms for a slab holding no triangle. */
#define QUERY_THIN 2.0f
#define QUERY_PARTS 8

gi_result gi__query_box(const struct gi_scene *s, const float lo[3], const float hi[3],
                        uint32_t **out, size_t *count, size_t *cap) {
  if (!s->rtc) return GI_OK;
  if (!gi__finite3(lo) || !gi__finite3(hi)) return GI_ERR_NONFINITE;
  if (lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]) return GI_OK;
  float ext[3], thin = INFINITY, wide = 0;
  for (int k = 0; k < 3; k++) {
    ext[k] = hi[k] - lo[k];
    thin = ext[k] < thin ? ext[k] : thin, wide = ext[k] > wide ? ext[k] : wide;
  }
  if (!(wide > QUERY_THIN * thin)) return query_sphere(s, lo, hi, out, count, cap);
  /* Parts of side `edge` (at least the thickness); their bounds tile the
   * box exactly (a shared face is one float), so every triangle over the
   * box is over some part; one over several is listed once. */
  float edge = thin > wide / QUERY_PARTS ? thin : wide / QUERY_PARTS;
  int np[3];
  for (int k = 0; k < 3; k++) {
    int n = (int)(ext[k] / edge + 0.5f);
    np[k] = n < 1 ? 1 : n > QUERY_PARTS ? QUERY_PARTS : n;
  }
  size_t first = *count;
  int i[3];
  for (i[2] = 0; i[2] < np[2]; i[2]++)
    for (i[1] = 0; i[1] < np[1]; i[1]++)
      for (i[0] = 0; i[0] < np[0]; i[0]++) {
        float plo[3], phi[3];
        for (int k = 0; k < 3; k++) {
          plo[k] = i[k] == 0 ? lo[k] : gi__minf(hi[k], lo[k] + ext[k] * (float)i[k] / (float)np[k]);
          phi[k] = i[k] + 1 == np[k] ? hi[k] : gi__minf(hi[k], lo[k] + ext[k] * (float)(i[k] + 1) / (float)np[k]);
        }
        gi_result rc = query_sphere(s, plo, phi, out, count, cap);
        if (rc != GI_OK) return rc;
      }
  size_t n = *count - first;
  gi__order_tris(s, *out + first, &n);
  *count = first + n;
  return GI_OK;
}
