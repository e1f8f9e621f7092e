/* near_field.c: a point or spot light close to a voxel's own surfaces.
 *
 * Injection lights each orientation group of a voxel at its centroid. A
 * light within a few patch radii lights the patch very unevenly (1/r^2
 * and the cosine change across it), so the centroid's value is wrong, and
 * wrong by a different amount for a coarse voxel than for its children:
 * a coarse voxel and the filter of its children then disagree, and the
 * probe jumps when a grid shift turns one into the other (11% beside a
 * street lamp on gi-walk's walk). Here each piece of triangle the voxel
 * owns (clipped as voxelizing clips it) receives exactly I * Omega, the
 * light's intensity times the solid angle the piece subtends, on the side
 * facing the light, when a shadow ray from the piece's centroid reaches
 * the light. The group's side irradiance is that flux over the group's
 * area: a coarse voxel's pieces are its children's pieces, so its own
 * light and its children's filtered light agree. The sun on a coarse
 * voxel is lit over its pieces for the same reason (gi__spread_light):
 * there the centroid's one shadow ray is the error, not 1/r^2. So are
 * the emitters (gi__spread_emitters): across a street of lit windows a
 * coarse voxel's centroid is no measure of its surface's light. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "light/light.h"
#include "scene/lights.h"

void gi__near_reset(gi_near_scratch *ns) { ns->have = ns->have_pieces = 0; }

void gi__near_free(gi_near_scratch *ns) {
  gi__free(ns->tris);
  gi__free(ns->pieces);
  memset(ns, 0, sizeof *ns);
}

/* One shadow ray from org toward point `to`, stopping GI_SHADOW_SHORTEN
 * short of it: 1 when nothing blocks it, 0 when something does, -1 (no
 * ray) when org is the point. Counts the ray in *rays. */
static int shadow_to(const gi_scene *s, const float org[3], const float to[3], uint64_t *rays) {
  float dir[3], tn = 0;
  for (int k = 0; k < 3; k++) dir[k] = to[k] - org[k];
  float len = gi__len(dir);
  if (!(len > 0)) return -1;
  for (int k = 0; k < 3; k++) dir[k] /= len;
  float tf = len * (1.f - GI_SHADOW_SHORTEN);
  uint8_t vis = 1;
  gi__occluded(s, 1, org, dir, &tn, &tf, &vis);
  (*rays)++;
  return vis;
}

/* Signed solid angle of triangle (a, b, c) seen from the origin (Van
 * Oosterom and Strackee). */
static float tri_solid_angle(const float a[3], const float b[3], const float c[3]) {
  float bc[3];
  gi__cross(b, c, bc);
  float la = gi__len(a), lb = gi__len(b), lc = gi__len(c);
  float num = gi__dot(a, bc);
  float den = la * lb * lc + gi__dot(a, b) * lc + gi__dot(a, c) * lb + gi__dot(b, c) * la;
  return 2.f * atan2f(num, den);
}

/* The voxel's triangles, queried once per voxel. */
static int voxel_tris(const gi_scene *s, double sz, const int64_t cell[3], gi_near_scratch *ns) {
  if (ns->have) return 0;
  float lo[3], hi[3];
  for (int a = 0; a < 3; a++) lo[a] = (float)((double)cell[a] * sz), hi[a] = (float)((double)(cell[a] + 1) * sz);
  ns->count = 0;
  if (gi__query_box(s, lo, hi, &ns->tris, &ns->count, &ns->cap) != GI_OK) return -1;
  ns->have = 1;
  return 0;
}

/* The piece's share in each group of g (its projected area along the
 * group's axes over its whole projected area); wsum[h] += share area.
 * Returns 0 when the piece shows in no group. */
static int piece_shares(const gi_vgeo *g, const float A[3], float area, float share[GI_VOX_GROUPS],
                        float wsum[GI_VOX_GROUPS]) {
  float proj = fabsf(A[0]) + fabsf(A[1]) + fabsf(A[2]);
  int any = 0;
  if (!(area > 0) || !(proj > 0)) return 0;
  for (int h = 0; h < g->groups; h++) {
    share[h] = 0;
    for (int a = 0; a < 3; a++) share[h] += g->face_side[2 * a] / 2 == h ? fabsf(A[a]) : 0.f;
    share[h] /= proj;
    if (share[h] > 0) wsum[h] += share[h] * area, any = 1;
  }
  return any;
}

int gi__near_field(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], const gi_lsample *l,
                   gi_near_scratch *ns, float Es[GI_VOX_FACES][3], uint64_t *rays) {
  if (voxel_tris(s, sz, cell, ns)) return -1;
  if (ns->count > GI_NEAR_MAX_TRIS) return 0;
  float P[3], I[3];
  for (int k = 0; k < 3; k++) P[k] = g->centroid[k] + l->dist * l->w[k], I[k] = l->V[k] * l->dist * l->dist;
  float flux[GI_VOX_GROUPS][2] = {{0}}, wsum[GI_VOX_GROUPS] = {0}, off = gi__shadow_offset((float)sz);
  for (size_t i = 0; i < ns->count; i++) {
    const uint32_t *ix = &s->indices[3 * ns->tris[i]];
    float tv[3][3], poly[GI_CLIP_MAXV][3], corner[3];
    for (int q = 0; q < 3; q++) memcpy(tv[q], &s->vertices[3 * ix[q]], sizeof(float[3]));
    int n = gi__voxel_clip_tri(sz, cell, (const float(*)[3])tv, poly, corner);
    if (n < 3) continue;
    /* Vector area, centroid and solid angle from P, by a fan over the piece. */
    float A[3] = {0, 0, 0}, C[3] = {0, 0, 0}, om = 0, v[GI_CLIP_MAXV][3];
    for (int q = 0; q < n; q++)
      for (int k = 0; k < 3; k++) v[q][k] = poly[q][k] + corner[k] - P[k];
    gi__fan_moments((const float(*)[3])v, n, A, C);
    for (int q = 1; q + 1 < n; q++) om += tri_solid_angle(v[0], v[q], v[q + 1]);
    float area = gi__len(A), share[GI_VOX_GROUPS] = {0};
    if (!piece_shares(g, A, area, share, wsum)) continue;
    for (int k = 0; k < 3; k++) C[k] /= area; /* relative to P */
    /* The piece's side facing the light: the normal n with n . (P - C) > 0. */
    float nrm[3], sg = gi__dot(A, C) < 0 ? 1.f : -1.f;
    for (int k = 0; k < 3; k++) nrm[k] = sg * A[k] / area;
    om = fabsf(om);
    if (!(om > 0)) continue;
    /* One shadow ray from the piece's centroid, off the surface toward the light. */
    float org[3];
    for (int k = 0; k < 3; k++) org[k] = C[k] + P[k] + off * nrm[k];
    if (shadow_to(s, org, P, rays) <= 0) continue;
    for (int h = 0; h < g->groups; h++)
      if (share[h] > 0) flux[h][gi__dot(g->u.fin.orient[h], nrm) >= 0 ? 0 : 1] += share[h] * om;
  }
  int mask = 0;
  for (int h = 0; h < g->groups; h++) {
    if (!(wsum[h] > 0)) continue;
    mask |= 1 << h;
    for (int sd = 0; sd < 2; sd++)
      for (int k = 0; k < 3; k++) Es[2 * h + sd][k] += flux[h][sd] / wsum[h] * I[k];
  }
  return mask;
}

/* Spread light: at most this many triangles in the voxel (more keep the
 * centroid's ray: clipping them all would cost more than the light). */
#define SUN_MAX_TRIS 512

/* A point on polygon v (n vertices, total area `area`): u in [0, 1) picks
 * the fan triangle by area and, by what is left of it, the distance from
 * v[0]; r2 the place across. With u and r2 stratified the points spread
 * over the polygon instead of clumping (a Hammersley set on one triangle). */
static void polygon_point(const float v[][3], int n, float area, float u, float r2, float out[3]) {
  float acc = 0, target = u * area, r1 = u;
  int t = 1;
  for (; t + 1 < n; t++) {
    float e1[3], e2[3], x[3];
    for (int k = 0; k < 3; k++) e1[k] = v[t][k] - v[0][k], e2[k] = v[t + 1][k] - v[0][k];
    gi__cross(e1, e2, x);
    float a = 0.5f * gi__len(x);
    if (acc + a >= target || t + 2 >= n) {
      r1 = a > 0 ? gi__minf(gi__maxf((target - acc) / a, 0.f), 1.f) : 0.5f;
      break;
    }
    acc += a;
  }
  if (t + 1 >= n) t = n - 2;
  float sr = sqrtf(r1), a = 1 - sr, b = sr * (1 - r2), c = sr * r2;
  for (int k = 0; k < 3; k++) out[k] = a * v[0][k] + b * v[t][k] + c * v[t + 1][k];
}

/* The stride by which points take the m samples (point j takes sample
 * j * stride mod m): coprime with m, so neighbouring points (along the
 * pieces) take samples far apart in their strata (the sky's elevation)
 * instead of pairing stratum with place. */
static int sample_stride(int m) {
  static const int strides[] = {7, 5, 3, 11, 13};
  for (size_t i = 0; i < sizeof strides / sizeof strides[0]; i++) {
    int a = m, b = strides[i];
    while (b) {
      int t = a % b;
      a = b, b = t;
    }
    if (a == 1 && strides[i] < m) return strides[i];
  }
  return 1;
}

/* One piece of the voxel's surface: its polygon (relative to the cell's
 * corner), vector area, share in each group, and the area of the pieces
 * up to and including it (cum). */
typedef struct gi_piece {
  float v[GI_CLIP_MAXV][3];
  float A[3], area, cum, share[GI_VOX_GROUPS];
  float c[3];     /* centroid, relative to the cell's corner */
  int n;
  uint8_t hidden; /* bit 0: the side A faces is hidden (hidden_side), bit 1: the other */
} gi_piece;

/* A piece within this angle of parallel to another can hide it (60 degrees). */
#define HIDE_COS 0.5f
/* A voxel of more pieces keeps them all: the pairs cost O(pieces^2), and
 * with no cap the city's injection took 36% longer (32: 4%). */
#define HIDE_MAX_PIECES 32

/* 1 when x (in q's plane) lies inside q's convex polygon, wound as q->A. */
static int in_piece(const gi_piece *q, const float x[3]) {
  for (int k = 0; k < q->n; k++) {
    const float *a = q->v[k], *b = q->v[(k + 1) % q->n];
    float e[3], r[3], cr[3];
    for (int m = 0; m < 3; m++) e[m] = b[m] - a[m], r[m] = x[m] - a[m];
    gi__cross(e, r, cr);
    if (gi__dot(cr, q->A) < -1e-6f * q->area * q->area) return 0;
  }
  return 1;
}

/* 1 when another piece of the voxel (size sz) lies in front of piece i's
 * centroid along unit n, inside the cell: that side of piece i is hidden
 * from outside the voxel (a wall 0.3 m behind a facade, inside the
 * building). Pieces more than 60 degrees off parallel are not asked (a
 * wall meeting a floor). The ray meets the pieces here: Embree's rays
 * for every piece cost the city's bake 40% more shadow rays. */
static int hidden_side(const gi_piece *pcs, size_t np, size_t i, const float n[3], float sz) {
  const gi_piece *p = &pcs[i];
  float tmax = INFINITY;
  for (int k = 0; k < 3; k++) {
    if (n[k] > 0) tmax = gi__minf(tmax, (sz - p->c[k]) / n[k]);
    else if (n[k] < 0) tmax = gi__minf(tmax, -p->c[k] / n[k]);
  }
  for (size_t j = 0; j < np; j++) {
    const gi_piece *q = &pcs[j];
    float an = gi__dot(q->A, n), d[3], x[3];
    if (j == i || fabsf(an) < HIDE_COS * q->area) continue;
    for (int k = 0; k < 3; k++) d[k] = q->c[k] - p->c[k];
    float t = gi__dot(q->A, d) / an;
    if (!(t > 1e-3f * sz) || t >= tmax) continue;
    for (int k = 0; k < 3; k++) x[k] = p->c[k] + t * n[k];
    if (in_piece(q, x)) return 1;
  }
  return 0;
}

/* Clips the voxel's triangles once (the sun's and the sky's calls share
 * them): pieces, cumulative areas, group areas, and which sides of each
 * piece other pieces hide. -1 when out of memory. */
static int voxel_pieces(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], gi_near_scratch *ns) {
  if (ns->have_pieces) return 0;
  if (ns->pieces_cap < ns->count) {
    gi_piece *pc = gi__realloc(ns->pieces, ns->count * sizeof *pc);
    if (!pc) return -1;
    ns->pieces = pc, ns->pieces_cap = ns->count;
  }
  memset(ns->wsum, 0, sizeof ns->wsum);
  memset(ns->wside, 0, sizeof ns->wside);
  ns->total = 0;
  ns->npieces = 0;
  for (size_t i = 0; i < ns->count; i++) {
    const uint32_t *ix = &s->indices[3 * ns->tris[i]];
    float tv[3][3], corner[3], C[3] = {0, 0, 0};
    gi_piece *pc = &ns->pieces[ns->npieces];
    for (int q = 0; q < 3; q++) memcpy(tv[q], &s->vertices[3 * ix[q]], sizeof(float[3]));
    pc->n = gi__voxel_clip_tri(sz, cell, (const float(*)[3])tv, pc->v, corner);
    if (pc->n < 3) continue;
    memset(pc->A, 0, sizeof pc->A);
    gi__fan_moments((const float(*)[3])pc->v, pc->n, pc->A, C);
    pc->area = gi__len(pc->A);
    memset(pc->share, 0, sizeof pc->share);
    if (!piece_shares(g, pc->A, pc->area, pc->share, ns->wsum)) continue;
    for (int k = 0; k < 3; k++) pc->c[k] = C[k] / pc->area;
    ns->total += pc->area;
    pc->cum = ns->total;
    ns->npieces++;
  }
  int ask = ns->npieces <= HIDE_MAX_PIECES;
  for (size_t i = 0; i < ns->npieces; i++) {
    gi_piece *pc = &ns->pieces[i];
    pc->hidden = 0;
    for (int t = 0; t < 2; t++) {
      float n[3];
      for (int k = 0; k < 3; k++) n[k] = (t ? -1.f : 1.f) * pc->A[k] / pc->area;
      if (ask && hidden_side(ns->pieces, ns->npieces, i, n, (float)sz)) {
        pc->hidden |= (uint8_t)(1u << t);
        continue;
      }
      for (int h = 0; h < g->groups; h++)
        if (pc->share[h] > 0) ns->wside[h][gi__dot(g->u.fin.orient[h], n) >= 0 ? 0 : 1] += pc->share[h] * pc->area;
    }
  }
  ns->have_pieces = 1;
  return 0;
}

/* Each group side's flux over the area of the group's pieces seen from
 * that side (wside; the group's whole area, wsum, when other pieces hide
 * them all) into Es; returns the groups that have area. */
static int sides_from_flux(const gi_vgeo *g, const float wsum[GI_VOX_GROUPS], const float wside[][2],
                           const float flux[][2][3], float Es[GI_VOX_FACES][3]) {
  int mask = 0;
  for (int h = 0; h < g->groups; h++) {
    if (!(wsum[h] > 0)) continue;
    mask |= 1 << h;
    for (int sd = 0; sd < 2; sd++) {
      float w = wside[h][sd] > 0 ? wside[h][sd] : wsum[h];
      for (int k = 0; k < 3; k++) Es[2 * h + sd][k] += flux[h][sd][k] / w;
    }
  }
  return mask;
}

/* The voxel's pieces for spreading light over them, and its corner: 1
 * when ready, 0 when it has none or too many triangles (the caller
 * samples at its centroids), -1 when out of memory. */
static int spread_pieces(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], gi_near_scratch *ns,
                         float corner[3]) {
  if (voxel_tris(s, sz, cell, ns)) return -1;
  if (ns->count == 0 || ns->count > SUN_MAX_TRIS) return 0;
  if (voxel_pieces(s, g, sz, cell, ns)) return -1;
  if (ns->npieces == 0 || !(ns->total > 0)) return 0;
  for (int a = 0; a < 3; a++) corner[a] = (float)(cell[a] * sz);
  return 1;
}

int gi__spread_light(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], const gi_lsample *ls,
                     int m, uint64_t *rng, gi_near_scratch *ns, float Es[GI_VOX_FACES][3], uint64_t *rays) {
  if (m < 1) return 0;
  float corner[3];
  int ready = spread_pieces(s, g, sz, cell, ns, corner);
  if (ready <= 0) return ready;
  float total = ns->total;
  /* P points over the surface, stratified by area along the pieces and
   * across each; each point's ray says whether its piece sees its sample's
   * light there. Each point stands for total / P of the area. */
  int P = m > GI_SUN_POINTS ? m : GI_SUN_POINTS;
  float flux[GI_VOX_GROUPS][2][3] = {{{0}}}, off = gi__shadow_offset((float)sz);
  float rot = gi__u01(rng), rot2 = gi__u01(rng);
  int stride = sample_stride(m);
  /* The points' rays go out as one stream (a call per ray cost the city's
   * injection its Embree setup 317k times); a point keeps its piece and
   * sample for the sum after. */
  float org[GI_SPREAD_MAX_POINTS][3], dir[GI_SPREAD_MAX_POINTS][3], tn[GI_SPREAD_MAX_POINTS],
      tf[GI_SPREAD_MAX_POINTS];
  uint8_t vis[GI_SPREAD_MAX_POINTS];
  struct { uint32_t piece; int sample; } at[GI_SPREAD_MAX_POINTS];
  int nr = 0;
  size_t i = 0;
  if (P > GI_SPREAD_MAX_POINTS) P = GI_SPREAD_MAX_POINTS;
  for (int j = 0; j < P; j++) {
    int si = (int)(((int64_t)j * stride) % m);
    const gi_lsample *l = &ls[si];
    float u = ((float)j + rot) / (float)P * total, r2 = gi__radical2_rot((uint32_t)j, rot2);
    while (i + 1 < ns->npieces && ns->pieces[i].cum < u) i++;
    const gi_piece *pc = &ns->pieces[i];
    float lo = pc->cum - pc->area;
    float cw = gi__dot(pc->A, l->w) / pc->area;
    /* A side other pieces hide sends no light out of the voxel (sides_from_flux). */
    if (cw == 0 || (pc->hidden >> (cw > 0 ? 0 : 1) & 1)) continue;
    /* The side facing the light; its point, off the surface toward it. */
    float sg = cw > 0 ? 1.f : -1.f, pt[3];
    polygon_point((const float(*)[3])pc->v, pc->n, pc->area, gi__minf(gi__maxf((u - lo) / pc->area, 0.f), 0.99999f),
                  r2, pt);
    for (int k = 0; k < 3; k++) org[nr][k] = pt[k] + corner[k] + off * sg * pc->A[k] / pc->area;
    memcpy(dir[nr], l->w, sizeof dir[nr]);
    tn[nr] = 0, tf[nr] = INFINITY;
    at[nr].piece = (uint32_t)i, at[nr].sample = si;
    nr++;
  }
  gi__occluded(s, nr, &org[0][0], &dir[0][0], tn, tf, vis);
  *rays += (uint64_t)nr;
  for (int r = 0; r < nr; r++) {
    if (!vis[r]) continue;
    const gi_piece *pc = &ns->pieces[at[r].piece];
    const gi_lsample *l = &ls[at[r].sample];
    float cw = gi__dot(pc->A, l->w) / pc->area, nrm[3];
    for (int k = 0; k < 3; k++) nrm[k] = (cw > 0 ? 1.f : -1.f) * pc->A[k] / pc->area;
    /* One sample estimates its point's irradiance as m V cos (V holds 1 / m). */
    float a = fabsf(cw) * total / (float)P * (float)m;
    for (int h = 0; h < g->groups; h++) {
      if (!(pc->share[h] > 0)) continue;
      int sd = gi__dot(g->u.fin.orient[h], nrm) >= 0 ? 0 : 1;
      for (int k = 0; k < 3; k++) flux[h][sd][k] += pc->share[h] * a * l->V[k];
    }
  }
  /* Each side's flux over all the group's pieces, as gi__near_field and as
   * the filter of the voxel's children weigh it. Counting only the pieces
   * wound toward a side (the side centroid's rule) put the drive's worst
   * shift back to 7.3% (sun alone; 0.64% this way). */
  return sides_from_flux(g, ns->wsum, (const float(*)[2])ns->wside, (const float(*)[2][3])flux, Es);
}

/* A random permutation of 0..m-1 into perm (Fisher-Yates). */
static void shuffle(int *perm, int m, uint64_t *rng) {
  for (int j = 0; j < m; j++) perm[j] = j;
  for (int j = m - 1; j > 0; j--) {
    int r = (int)(gi__u01(rng) * (float)(j + 1));
    if (r > j) r = j;
    int t = perm[j];
    perm[j] = perm[r], perm[r] = t;
  }
}

/* A point of stratum k of m in [0, 1). */
static float stratum(int k, int m, uint64_t *rng) {
  return gi__minf(((float)k + gi__u01(rng)) / (float)m, 0.99999994f);
}

/* One light sample of pick pk at point pt (unit normal n0 of its piece,
 * shadow offset off), weighed against one cosine ray per side: its shadow
 * ray (org, dir, *tf) and what it brings when nothing blocks it (E, on
 * side *sd; 0 is the side n0 faces). 0 when it brings nothing and needs
 * no ray: *tf is then -1, a ray gi__occluded skips. */
static int emitter_sample_at(const gi_scene *s, const gi_emitter_pick *pk, float r2, const float pt[3],
                             const float n0[3], float off, uint8_t hidden, float org[3], float dir[3], float *tf,
                             float E[3], int8_t *sd) {
  gi_lsample l;
  float cw, len, to[3];
  *tf = -1.f;
  memset(org, 0, sizeof(float[3])), memset(dir, 0, sizeof(float[3]));
  if (!gi__emitter_sample_at(s, pk, r2, pt, &l) || (cw = gi__dot(n0, l.w)) == 0) return 0;
  *sd = cw > 0 ? 0 : 1;
  if (hidden >> *sd & 1) return 0; /* a side other pieces hide sends nothing out (sides_from_flux) */
  for (int k = 0; k < 3; k++) org[k] = pt[k] + (*sd ? -off : off) * n0[k], to[k] = pt[k] + l.dist * l.w[k];
  for (int k = 0; k < 3; k++) dir[k] = to[k] - org[k];
  if (!((len = gi__len(dir)) > 0)) return 0; /* shadow_to's rule: no ray from the point itself */
  for (int k = 0; k < 3; k++) dir[k] /= len;
  *tf = len * (1.f - GI_SHADOW_SHORTEN);
  float f = gi__mis_light(l.mpl, fabsf(cw) / GI_PI_F, 0) * fabsf(cw);
  for (int k = 0; k < 3; k++) E[k] = f * l.V[k];
  return 1;
}

/* gi__spread_emitters' cosine rays, as streams: ray r from co[r]
 * along cw[r] past ctn[r], pdf cpb[r] and cosine cz[r], adds what it finds
 * to Ec of its point and side (who[r] = 2 point + side). p is where the
 * picks were made from. */
static void cosine_rays(const gi_scene *s, const float p[3], int nc, const float (*co)[3], const float (*cw)[3],
                        const float *ctn, const float *cpb, const float *cz, const int16_t *who,
                        float (*Ec)[2][3]) {
  for (int b = 0; b < nc; b += GI_EMIT_RAYS) {
    int nb = nc - b < GI_EMIT_RAYS ? nc - b : GI_EMIT_RAYS;
    float V[GI_EMIT_RAYS][3];
    uint8_t hit[GI_EMIT_RAYS];
    gi__emitter_rays(s, p, nb, co + b, cw + b, ctn + b, 1, cpb + b, 0, V, hit);
    for (int r = 0; r < nb; r++)
      if (hit[r])
        for (int k = 0; k < 3; k++) Ec[who[b + r] / 2][who[b + r] % 2][k] += V[r][k] * cz[b + r];
  }
}

/* Adds what a point of piece pc standing for area wpt receives (E: on the
 * side the piece's winding faces, 0, and the other) to its groups' sides. */
static void piece_flux(const gi_vgeo *g, const gi_piece *pc, float wpt, const float E[2][3],
                       float flux[GI_VOX_GROUPS][2][3]) {
  float n0[3];
  for (int k = 0; k < 3; k++) n0[k] = pc->A[k] / pc->area;
  for (int h = 0; h < g->groups; h++) {
    if (!(pc->share[h] > 0)) continue;
    int gs = gi__dot(g->u.fin.orient[h], n0) >= 0 ? 0 : 1; /* the group side n0 faces */
    for (int k = 0; k < 3; k++) {
      flux[h][gs][k] += pc->share[h] * wpt * E[0][k];
      flux[h][gs ^ 1][k] += pc->share[h] * wpt * E[1][k];
    }
  }
}

int gi__spread_emitters(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], int m, uint64_t *rng,
                        gi_near_scratch *ns, float Es[GI_VOX_FACES][3], uint64_t *rays) {
  if (m < 1 || s->num_emitters == 0) return 0;
  if (m > GI_SPREAD_MAX_POINTS) m = GI_SPREAD_MAX_POINTS;
  float corner[3];
  int ready = spread_pieces(s, g, sz, cell, ns, corner);
  if (ready <= 0) return ready;
  float total = ns->total;
  float flux[GI_VOX_GROUPS][2][3] = {{{0}}}, off = gi__shadow_offset((float)sz), wpt = total / (float)m;
  float rot = gi__u01(rng), rot2 = gi__u01(rng);
  /* Point j takes pick perm[j] (stratum perm[j] of the light tree's u), perm a
   * random permutation (Latin hypercube): the picks stay stratified and
   * the pairing of place and stratum is random. A fixed pairing (a stride,
   * as the sky's) is biased where the light depends on both, as a window's
   * does on where the point and the window's sample lie: +4.8% at 16
   * samples over test_emitter_spread's plate. The same for the place on
   * the window (pw) and the cosine rays' two dimensions (pu, pv). With one
   * unstratified ray per point the spread read noisier than the
   * centroid's 16 stratified ones, and a street probe jumped more at grid
   * shifts (1.6% against 0.7%). */
  int perm[GI_SPREAD_MAX_POINTS], pw[GI_SPREAD_MAX_POINTS], pu[GI_SPREAD_MAX_POINTS], pv[GI_SPREAD_MAX_POINTS];
  shuffle(perm, m, rng), shuffle(pw, m, rng), shuffle(pu, m, rng), shuffle(pv, m, rng);
  /* The picks are made from the voxel's centroid, m strata in one walk
   * down the tree (a walk per point cost the city's injection 6 ms of its
   * 208). Each point weighs its sample, and the cosine rays weigh what
   * they find, by that same strategy's pdf, so the estimate stays
   * unbiased; only its noise depends on the proposal. */
  gi_emitter_pick picks[GI_SPREAD_MAX_POINTS];
  if (!gi__emitter_picks(s, g->centroid, m, rng, picks)) return 0;
  size_t i = 0, faced = SIZE_MAX;
  int ahead[2] = {0, 0};
  float n[2][3], t[2][3], bt[2][3]; /* per side of the piece: its normal and tangents */
  /* The points' light samples trace as one stream after the loop (as
   * gi__spread_light's); each point keeps its piece and its cosine rays'
   * light until then. */
  float org[GI_SPREAD_MAX_POINTS][3], dir[GI_SPREAD_MAX_POINTS][3], tn[GI_SPREAD_MAX_POINTS], tf[GI_SPREAD_MAX_POINTS];
  float El[GI_SPREAD_MAX_POINTS][3], Ec[GI_SPREAD_MAX_POINTS][2][3];
  uint32_t piece[GI_SPREAD_MAX_POINTS];
  int8_t side[GI_SPREAD_MAX_POINTS];
  uint8_t vis[GI_SPREAD_MAX_POINTS];
  /* Up to two cosine rays per point, traced after the loop. */
  float co[2 * GI_SPREAD_MAX_POINTS][3], cw[2 * GI_SPREAD_MAX_POINTS][3], ctn[2 * GI_SPREAD_MAX_POINTS];
  float cpb[2 * GI_SPREAD_MAX_POINTS], cz[2 * GI_SPREAD_MAX_POINTS];
  int16_t cwho[2 * GI_SPREAD_MAX_POINTS];
  int nc = 0;
  uint64_t traced = 0;
  for (int j = 0; j < m; j++) {
    float u = ((float)j + rot) / (float)m * total;
    while (i + 1 < ns->npieces && ns->pieces[i].cum < u) i++;
    const gi_piece *pc = &ns->pieces[i];
    float lo = pc->cum - pc->area, n0[3], pt[3];
    for (int k = 0; k < 3; k++) n0[k] = pc->A[k] / pc->area;
    if (faced != i) {
      /* A side of the piece's plane that no emitter lies in front of finds
       * none: its cosine rays are skipped (a box's outside, a floor's
       * underside). One test per piece: it holds on the whole plane. */
      float nn[3], p0[3];
      for (int k = 0; k < 3; k++) nn[k] = -n0[k], p0[k] = pc->v[0][k] + corner[k];
      ahead[0] = gi__light_tree_ahead(s, p0, n0), ahead[1] = gi__light_tree_ahead(s, p0, nn);
      for (int sd = 0; sd < 2; sd++) {
        memcpy(n[sd], sd ? nn : n0, sizeof n[sd]);
        gi__basis(n[sd], t[sd], bt[sd]);
      }
      faced = i;
    }
    polygon_point((const float(*)[3])pc->v, pc->n, pc->area, gi__minf(gi__maxf((u - lo) / pc->area, 0.f), 0.99999f),
                  gi__radical2_rot((uint32_t)j, rot2), pt);
    for (int k = 0; k < 3; k++) pt[k] += corner[k];
    piece[j] = (uint32_t)i;
    tn[j] = 0;
    traced += (uint64_t)emitter_sample_at(s, &picks[perm[j]], stratum(pw[j], m, rng), pt, n0, off, pc->hidden,
                                          org[j], dir[j], &tf[j], El[j], &side[j]);
    /* A cosine-weighted ray on each side: near, large emitters (inject.c).
     * It leaves from the point itself and skips the first `off` of its
     * way (it climbs away from the piece's plane, so that plane cannot
     * stop it): started off the surface, it measured the light `off`
     * nearer the window than the point, +9% under a window 0.1 voxel away. */
    memset(Ec[j], 0, sizeof Ec[j]);
    for (int sd = 0; sd < 2; sd++) {
      float u1 = stratum(pu[j], m, rng), u2 = stratum(pv[j], m, rng);
      /* Its numbers drawn all the same: the next ray's stay as they were. */
      if (!ahead[sd] || (pc->hidden >> sd & 1)) continue;
      float z = gi__cosine_dir(t[sd], bt[sd], n[sd], u1, u2, cw[nc]);
      memcpy(co[nc], pt, sizeof co[nc]);
      ctn[nc] = off, cz[nc] = z, cpb[nc] = z / GI_PI_F, cwho[nc++] = (int16_t)(2 * j + sd);
    }
  }
  gi__occluded(s, m, &org[0][0], &dir[0][0], tn, tf, vis);
  *rays += traced + (uint64_t)nc;
  /* The light strategy's pdf for what they find: the picks', made from the centroid. */
  cosine_rays(s, g->centroid, nc, (const float(*)[3])co, (const float(*)[3])cw, ctn, cpb, cz, cwho, Ec);
  for (int j = 0; j < m; j++) {
    float E[2][3] = {{0}}; /* irradiance on the side the piece faces (0) and the other (1) */
    if (tf[j] >= 0 && vis[j]) memcpy(E[side[j]], El[j], sizeof E[0]);
    for (int sd = 0; sd < 2; sd++)
      for (int k = 0; k < 3; k++) E[sd][k] += Ec[j][sd][k];
    piece_flux(g, &ns->pieces[piece[j]], wpt, (const float(*)[3])E, flux);
  }
  return sides_from_flux(g, ns->wsum, (const float(*)[2])ns->wside, (const float(*)[2][3])flux, Es);
}
