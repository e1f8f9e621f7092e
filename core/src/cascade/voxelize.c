/* voxelize.c: triangles into each level's geometry buffer.
 *
 * Per level, a BVH query returns only the triangles overlapping the level's
 * window (never a scan of the scene); triangles entirely inside the region
 * the finer level covers are skipped, since that region is filtered.
 * Triangles are binned into slabs of cells along z, and slabs are
 * voxelized in parallel: each worker writes only its own slabs, so no
 * locks. Each triangle is clipped exactly against every cell of its bounds
 * (Sutherland-Hodgman); the clipped polygon gives the area, centroid and
 * vector area the cell receives. A polygon belongs to a cell when its
 * centroid is inside the half-open cell [lo, hi): a face lying exactly on
 * a cell border is counted once, in the upper cell. */
#include <stdlib.h>
#include <string.h>
#include "cascade/cascade_internal.h"
#include "base/internal.h"

#define SLAB 2 /* cells per z-slab */
/* Each slab is voxelized as BANDS tasks, a band of R / BANDS rows (y)
 * each: on a flat city with z up, a coarse level's geometry lies in one
 * or two z-slabs, and a task per slab left one thread with the level
 * (Munich's voxelization ran 1.29x faster on 2 threads than on 1). A
 * cell takes its triangles in the same order either way. */
#define BANDS 4
/* The serial binning of a level checks the cancel token this often: a
 * coarse level of a large city holds every triangle. */
#define GI_CANCEL_EVERY_TRIS 8192
#define MAXV GI_CLIP_MAXV

/* A task's (a slab's band's) voxels that hold geometry, finalized, in
 * the bake's order (z, y, x from the window's first cell), nz[l] of them
 * in the slab's layer l: the level's entries are taken from these in
 * slab, layer, band order once every task is done. */
typedef struct {
  uint32_t n, nz[SLAB];
  uint32_t *slot;
  gi_vgeo *geo;
} slab_out;

/* Every level's tasks run in one parallel loop: task q is level
 * q / per_level's task q % per_level (slab * BANDS + band). A loop per
 * level woke the other thread six times per bake for 1-3 ms of work
 * each, and on the 2-vCPU VMs a wake-up now and then took 3-5 ms. */
typedef struct {
  struct gi_cascade *c;
  size_t per_level;
  const uint32_t *bin_start[GI_MAX_LEVELS]; /* per level, per task, into bin_tris */
  const uint32_t *bin_tris[GI_MAX_LEVELS];
  gi_vgeo **scratch;         /* per worker: one task's sums, SLAB x R / BANDS x R, zeroed between tasks */
  slab_out *out;             /* per task, every level's */
  atomic_int failed;         /* a worker ran out of memory */
} vox_ctx;

/* Clips polygon (n vertices) against axis a: keep x[a] >= lo if sign>0, else x[a] <= hi. */
static int clip_plane(float in[][3], int n, float out[][3], int a, float bound, int keep_above) {
  int m = 0;
  for (int i = 0; i < n; i++) {
    const float *p = in[i], *q = in[(i + 1) % n];
    float dp = keep_above ? p[a] - bound : bound - p[a];
    float dq = keep_above ? q[a] - bound : bound - q[a];
    if (dp >= 0) {
      memcpy(out[m++], p, sizeof(float[3]));
    }
    if ((dp >= 0) != (dq >= 0)) {
      float t = dp / (dp - dq);
      for (int k = 0; k < 3; k++) out[m][k] = p[k] + t * (q[k] - p[k]);
      out[m][a] = bound; /* exact on the plane */
      m++;
    }
    if (m >= MAXV - 1) break;
  }
  return m;
}

/* A piece counts toward its side's front (gi_vgeo afront) when its normal
 * lies within 60 degrees of the axis. */
#define FRONT_COS 0.5f

static void accumulate(gi_vgeo *g, const float poly[][3], int n, const float corner[3], float s,
                       const gi_material *mat) {
  /* Vector area and area-weighted centroid by fan triangulation. */
  float A[3] = {0, 0, 0}, C[3] = {0, 0, 0};
  gi__fan_moments(poly, n, A, C);
  float area = gi__len(A);
  if (!(area > 0)) return;
  float gloss[3];
  gi__gloss_rgb(mat, gloss);
  float *T = g->u.sum.tensor;
  /* area n n^T = A A^T / area: the same for either winding. */
  float ia = 1.f / area;
  T[0] += A[0] * A[0] * ia, T[1] += A[1] * A[1] * ia, T[2] += A[2] * A[2] * ia;
  T[3] += A[0] * A[1] * ia, T[4] += A[0] * A[2] * ia, T[5] += A[1] * A[2] * ia;
  g->area += area;
  for (int k = 0; k < 3; k++) {
    g->albedo[k] += area * mat->albedo[k];
    g->emission[k] += area * mat->emission[k];
    /* C is area-weighted already; it is relative to the cell corner. */
    float ck = C[k] + area * corner[k];
    g->centroid[k] += ck;
    g->proj[k] += fabsf(A[k]);
    for (int a = 0; a < 3; a++) g->u.sum.acen[a][k] += fabsf(A[a]) * ia * ck;
    if (A[k] > 0) g->u.sum.apos[k] += A[k];
    /* Along axis k itself, the two signs of the normal apart (side_offsets). */
    if (fabsf(A[k]) >= FRONT_COS * area) {
      float rel = C[k] * ia, *front = &g->u.sum.afront[k][A[k] < 0];
      *front = gi__maxf(*front, A[k] > 0 ? s + rel : 2 * s - rel);
    }
  }
  for (int k = 0; k < 3; k++) g->gloss[k] += area * gloss[k];
}

int gi__voxel_clip_tri(double s, const int64_t cell[3], const float tv[3][3], float poly[GI_CLIP_MAXV][3],
                       float corner[3]) {
  float sz = (float)s;
  for (int a = 0; a < 3; a++) corner[a] = (float)(cell[a] * s);
  float pb[MAXV][3];
  for (int q = 0; q < 3; q++)
    for (int a = 0; a < 3; a++) poly[q][a] = tv[q][a] - corner[a];
  int n = 3;
  for (int a = 0; a < 3 && n >= 3; a++) {
    /* Every vertex within the slab along a: both clips would copy the
     * polygon as it is (most of a coarse voxel's triangles, along most
     * axes). */
    int inside = 1;
    for (int q = 0; q < n && inside; q++) inside = poly[q][a] >= 0.f && sz - poly[q][a] >= 0.f;
    if (inside) continue;
    n = clip_plane(poly, n, pb, a, 0.f, 1);
    if (n < 3) break;
    n = clip_plane(pb, n, poly, a, sz, 0);
  }
  if (n < 3) return 0;
  /* Half-open ownership by the polygon's centroid. */
  float cen[3] = {0, 0, 0};
  for (int q = 0; q < n; q++)
    for (int a = 0; a < 3; a++) cen[a] += poly[q][a] / (float)n;
  if (cen[0] >= sz || cen[1] >= sz || cen[2] >= sz) return 0;
  return n;
}

/* Clips triangle tv against global cell `cell` (size s) and adds the
 * piece it owns to that voxel's sums g. Shared with the move
 * (move/move.c): one code path, so a voxel rebuilt after a scroll is
 * bit-identical. */
void gi__voxel_add_tri(gi_vgeo *g, double s, const int64_t cell[3], const float tv[3][3], const gi_material *mat) {
  float pa[MAXV][3], corner[3];
  int n = gi__voxel_clip_tri(s, cell, tv, pa, corner);
  if (n) accumulate(g, (const float(*)[3])pa, n, corner, (float)s, mat);
}

static void voxelize_slabs(void *p, size_t b, size_t e, int worker) {
  vox_ctx *v = p;
  struct gi_cascade *c = v->c;
  const gi_scene *s = c->scene;
  int R = c->R;
  gi_vgeo *sums = v->scratch[worker];
  int RB = R / BANDS;
  size_t plane = (size_t)RB * R;
  for (size_t q = b; q < e; q++) {
    int d = (int)(q / v->per_level);
    size_t task = q % v->per_level, slab = task / BANDS;
    gi_level *L = &c->lv[d];
    const uint32_t *bin_start = v->bin_start[d], *bin_tris = v->bin_tris[d];
    int64_t k0 = L->cell0[2] + (int64_t)slab * SLAB, k1 = k0 + SLAB;
    int64_t j0 = L->cell0[1] + (int64_t)(task % BANDS) * RB, j1 = j0 + RB;
    if (k1 > L->cell0[2] + R) k1 = L->cell0[2] + R;
    memset(sums, 0, (size_t)SLAB * plane * sizeof *sums);
    for (uint32_t bi = bin_start[task]; bi < bin_start[task + 1]; bi++) {
      uint32_t t = bin_tris[bi];
      const uint32_t *ix = &s->indices[3 * t];
      float tv[3][3];
      float tlo[3], thi[3];
      for (int q = 0; q < 3; q++) {
        memcpy(tv[q], &s->vertices[3 * ix[q]], sizeof(float[3]));
      }
      for (int a = 0; a < 3; a++) {
        tlo[a] = gi__minf(tv[0][a], gi__minf(tv[1][a], tv[2][a]));
        thi[a] = gi__maxf(tv[0][a], gi__maxf(tv[1][a], tv[2][a]));
      }
      int64_t c0[3], c1[3];
      for (int a = 0; a < 3; a++) {
        c0[a] = (int64_t)floor((double)tlo[a] / L->s);
        c1[a] = (int64_t)floor((double)thi[a] / L->s) + 1;
        if (c0[a] < L->cell0[a]) c0[a] = L->cell0[a];
        if (c1[a] > L->cell0[a] + R) c1[a] = L->cell0[a] + R;
      }
      if (c0[2] < k0) c0[2] = k0;
      if (c1[2] > k1) c1[2] = k1;
      if (c0[1] < j0) c0[1] = j0;
      if (c1[1] > j1) c1[1] = j1;
      gi_material tm;
      const gi_material *mat = gi__tri_material(s, t, &tm);
      for (int64_t k = c0[2]; k < c1[2]; k++)
        for (int64_t j = c0[1]; j < c1[1]; j++)
          for (int64_t i = c0[0]; i < c1[0]; i++) {
            if (gi__is_inner(L, i, j, k)) continue;
            int64_t cell[3] = {i, j, k};
            size_t w = (size_t)(k - k0) * plane + (size_t)(j - j0) * (size_t)R + (size_t)(i - L->cell0[0]);
            gi__voxel_add_tri(&sums[w], L->s, cell, (const float(*)[3])tv, mat);
          }
    }
    /* Finalize in the bake's order; keep the voxels that hold geometry. */
    size_t cells = (size_t)(k1 - k0) * plane;
    uint32_t n = 0;
    for (size_t w = 0; w < cells; w++) n += sums[w].area > 0;
    slab_out *o = &v->out[q];
    o->n = 0;
    memset(o->nz, 0, sizeof o->nz);
    if (n == 0) continue;
    o->slot = gi__malloc(n * sizeof *o->slot);
    o->geo = gi__malloc(n * sizeof *o->geo);
    if (!o->slot || !o->geo) {
      atomic_store(&v->failed, 1);
      return;
    }
    /* The scratch is in z, y, x order from the band's first cell. */
    for (size_t w = 0; w < cells; w++) {
      if (!(sums[w].area > 0)) continue;
      int64_t i = L->cell0[0] + (int64_t)(w % (size_t)R), j = j0 + (int64_t)(w / (size_t)R % (size_t)RB);
      int64_t cell[3] = {i, j, k0 + (int64_t)(w / plane)};
      uint32_t slot = gi__slot(cell[0], cell[1], cell[2], R);
      if (!gi__voxel_finalize(L, &sums[w], slot, cell)) continue;
      o->slot[o->n] = slot;
      o->geo[o->n++] = sums[w];
      o->nz[w / plane]++;
    }
  }
}

/* Axes whose surfaces lie within this angle of a group's share its
 * gathers (a tilted roof seen along two axes is one surface). */
#define GROUP_COS 0.866f /* 30 degrees */
/* An axis showing less than this share of the largest axis's projected
 * area takes the nearest group's light: too little surface to pay for
 * gathers of its own. */
#define GROUP_MINOR 0.25f

/* Below this share of the voxel's surface area, a side's area is rounding. */
#define SIDE_EPS 1e-4f

/* Per side sd = 2 h + t of each group h, how far along orient[h] the
 * pieces facing that side lie from the group's centroid gc[h] (soff),
 * and their projected area over the group's axes (sarea): along each
 * axis a of the group, side 0 (+orient) takes the pieces whose normal
 * has orient's sign on a. Only the axes' own coordinates are summed (a
 * slab's two faces differ across it, not along it). Along an axis the
 * side lies at its front-most piece (afront), so light and cones start
 * where the side is seen from: two parallel walls facing the street 0.55
 * m apart in one voxel (a Munich facade with another behind it) started
 * them between the walls, behind the outer one, which then shadowed the
 * sunlit facade (a street there read 0.69 of the reference's indirect
 * light). An axis without such a piece (its pieces all more than 60
 * degrees off it) says nothing of the side. corner: the cell's low
 * corner, s its size. */
static void side_offsets(const gi_vgeo *g, int G, const int grp[3], const float dir[][3], const float gc[][3],
                         const float corner[3], float s, float soff[2 * GI_VOX_GROUPS],
                         float sarea[2 * GI_VOX_GROUPS]) {
  float num[2 * GI_VOX_GROUPS] = {0}, den[2 * GI_VOX_GROUPS] = {0};
  memset(sarea, 0, 2 * GI_VOX_GROUPS * sizeof *sarea);
  for (int a = 0; a < 3; a++)
    for (int t = 0; t < 2; t++) {
      int h = grp[a], sd = 2 * h + t, neg = (dir[h][a] < 0) != t;
      float w = neg ? g->proj[a] - g->u.sum.apos[a] : g->u.sum.apos[a];
      /* A side this small is rounding (a vertical facade's sliver of
       * projection on the up axis), not area: taken as area, it hid the
       * sheet from sheet_minor_faces (a turned facade's voxel showed the
       * block's dark inside through its x face). */
      if (!(w > SIDE_EPS * g->area)) continue;
      sarea[sd] += w;
      float front = g->u.sum.afront[a][neg];
      if (!(front > 0)) continue;
      float disp = corner[a] + (neg ? 2 * s - front : front - s) - gc[h][a];
      num[sd] += w * disp * dir[h][a];
      den[sd] += w * dir[h][a] * dir[h][a];
    }
  for (int sd = 0; sd < 2 * GI_VOX_GROUPS; sd++) soff[sd] = sd < 2 * G && den[sd] > 0 ? num[sd] / den[sd] : 0.f;
}

/* The faces of minor axes of single-sheet groups (gi_vgeo.brighter): a
 * group whose pieces all face one of its sides (sarea, side_offsets), on
 * an axis other than the one its orientation leans on most. */
static uint8_t sheet_minor_faces(const int grp[3], const float dir[][3], const float sarea[2 * GI_VOX_GROUPS]) {
  uint8_t bits = 0;
  for (int a = 0; a < 3; a++) {
    int h = grp[a], dom = 0;
    for (int b = 1; b < 3; b++)
      if (fabsf(dir[h][b]) > fabsf(dir[h][dom])) dom = b;
    if (a != dom && (sarea[2 * h] > 0) != (sarea[2 * h + 1] > 0)) bits |= (uint8_t)(3u << (2 * a));
  }
  return bits;
}

/* The voxel's orientation groups from its normal tensor (see
 * cascade_internal.h): per axis a, N_a = M e_a; the largest axis first. */
static void orient_groups(gi_vgeo *g, const float corner[3], float s) {
  const float *T = g->u.sum.tensor;
  const float N[3][3] = {{T[0], T[3], T[4]}, {T[3], T[1], T[5]}, {T[4], T[5], T[2]}};
  float cen[3][3], dir[GI_VOX_GROUPS][3] = {{0}}, gc[GI_VOX_GROUPS][3] = {{0}}, gw[GI_VOX_GROUPS] = {0};
  for (int a = 0; a < 3; a++)
    for (int k = 0; k < 3; k++) cen[a][k] = g->proj[a] > 0 ? g->u.sum.acen[a][k] / g->proj[a] : g->centroid[k];
  int order[3] = {0, 1, 2}, grp[3], G = 0;
  for (int i = 1; i < 3; i++)
    for (int j = i; j > 0 && g->proj[order[j]] > g->proj[order[j - 1]]; j--) {
      int t = order[j];
      order[j] = order[j - 1], order[j - 1] = t;
    }
  for (int i = 0; i < 3; i++) {
    int a = order[i];
    float len = gi__len(N[a]), u[3] = {0, 0, 0};
    int seen = len > 1e-12f * g->area;
    if (seen)
      for (int k = 0; k < 3; k++) u[k] = N[a][k] / len;
    int best = 0;
    float bd = -1;
    for (int h = 0; h < G; h++) {
      float dd = fabsf(gi__dot(u, dir[h]));
      if (dd > bd) bd = dd, best = h;
    }
    int minor = !seen || g->proj[a] < GROUP_MINOR * g->proj[order[0]];
    if (G > 0 && (minor || bd >= GROUP_COS)) {
      grp[a] = best;
    } else {
      memcpy(dir[G], u, sizeof u);
      grp[a] = G++;
    }
    gw[grp[a]] += g->proj[a];
    for (int k = 0; k < 3; k++) gc[grp[a]][k] += g->proj[a] * cen[a][k];
  }
  for (int h = 0; h < G; h++)
    for (int k = 0; k < 3; k++) gc[h][k] = gw[h] > 0 ? gc[h][k] / gw[h] : g->centroid[k];
  float soff[2 * GI_VOX_GROUPS], sarea[2 * GI_VOX_GROUPS];
  side_offsets(g, G, grp, dir, gc, corner, s, soff, sarea);
  memset(&g->u, 0, sizeof g->u);
  for (int h = 0; h < G; h++) {
    memcpy(g->u.fin.orient[h], dir[h], sizeof dir[h]);
    memcpy(g->u.fin.gcen[h], gc[h], sizeof gc[h]);
  }
  memcpy(g->u.fin.soff, soff, sizeof soff);
  g->groups = (uint8_t)G;
  memcpy(g->normal, dir[0], sizeof g->normal);
  for (int f = 0; f < GI_VOX_FACES; f++) g->face_side[f] = gi__face_side(dir[grp[f / 2]], grp[f / 2], f);
  g->brighter = sheet_minor_faces(grp, dir, sarea);
}

/* Normalises one voxel's sums and derives its opacity; clears an empty
 * voxel. Returns 1 when it holds geometry. Shared with the move. */
int gi__voxel_finalize(gi_level *L, gi_vgeo *g, uint32_t slot, const int64_t cell[3]) {
  double s2 = L->s * L->s;
  gi_vrad *r = &L->rad[slot];
  memset(r, 0, sizeof *r); /* +0 in every half lane */
  if (!(g->area > 0)) {
    memset(g, 0, sizeof *g);
    return 0;
  }
  float ia = 1.f / g->area;
  for (int a = 0; a < 3; a++) {
    g->albedo[a] *= ia;
    g->emission[a] *= ia;
    g->centroid[a] *= ia;
  }
  for (int k = 0; k < 3; k++) g->gloss[k] *= ia;
  float corner[3];
  for (int a = 0; a < 3; a++) corner[a] = (float)((double)cell[a] * L->s);
  orient_groups(g, corner, (float)L->s);
  for (int a = 0; a < 3; a++) {
    double al = g->proj[a] / s2;
    if (al > GI_MAX_VOXEL_ALPHA) al = GI_MAX_VOXEL_ALPHA;
    r->h[GI_VRAD_ALPHA + a] = gi__f2h((float)al);
    r->h[GI_VRAD_TAU + a] = gi__f2h((float)-log(1.0 - al));
  }
  return 1;
}

/* Gives the tasks' voxels their entries, in the bake's order (slab,
 * layer, band), and lists them as the level's occupied voxels to light;
 * fill_entries fills the entries after. */
static gi_result gather_slabs(struct gi_cascade *c, int d, slab_out *out, int nslab, uint32_t nested,
                              gi_error_info *err) {
  gi_level *L = &c->lv[d];
  uint64_t n = 0;
  for (int t = 0; t < nslab * BANDS; t++) n += out[t].n;
  /* The level's own voxels and its `nested` cells above the finer level's: one allocation. */
  gi_result rc = gi__level_reserve(c, d, (L->used ? L->used : 1) + (uint32_t)n + nested, 0, err);
  if (rc != GI_OK) return rc;
  L->num_occ = 0;
  L->num_geo = 0;
  for (int sl = 0; sl < nslab; sl++) {
    uint32_t at[BANDS] = {0}; /* each band's next voxel */
    for (int l = 0; l < SLAB; l++)
      for (int bd = 0; bd < BANDS; bd++) {
        const slab_out *o = &out[sl * BANDS + bd];
        for (uint32_t q = at[bd]; q < at[bd] + o->nz[l]; q++) {
          gi__level_claim(L, o->slot[q]); /* filled by fill_entries */
          L->occ[L->num_occ++] = o->slot[q];
          L->num_geo++;
        }
        at[bd] += o->nz[l];
      }
  }
  return GI_OK;
}

/* The entries gather_slabs claimed, each from its task's sums: the
 * geometry copied, the light zeroed. Every level's tasks in one parallel
 * loop: serial, the copies (fresh memory, faulted in on first touch) were
 * 4-8 ms of every bake that no second thread shared. */
typedef struct {
  struct gi_cascade *c;
  const slab_out *out; /* per task, as vox_ctx's */
  size_t per_level;
} fill_ctx;

static void fill_entries(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  const fill_ctx *x = p;
  for (size_t t = b; t < e; t++) {
    gi_level *L = &x->c->lv[t / x->per_level];
    const slab_out *o = &x->out[t];
    for (uint32_t q = 0; q < o->n; q++) {
      uint32_t en = L->vix[o->slot[q]];
      gi__level_clear(L, en);
      L->geo[en] = o->geo[q];
    }
  }
}

/* A nested cell holds geometry exactly when one of its eight children
 * does (the filter then fills it). */
static int nested_any(const gi_level *F, int R, int64_t i, int64_t j, int64_t k) {
  for (int q = 0; q < 8; q++)
    if (F->vix[gi__slot(2 * i + (q & 1), 2 * j + (q >> 1 & 1), 2 * k + (q >> 2), R)] != 0) return 1;
  return 0;
}

#define FOR_NESTED(L, i, j, k)                                \
  for (int64_t k = (L)->inner0[2]; k < (L)->inner1[2]; k++)   \
    for (int64_t j = (L)->inner0[1]; j < (L)->inner1[1]; j++) \
      for (int64_t i = (L)->inner0[0]; i < (L)->inner1[0]; i++)

uint32_t gi__nested_need(const struct gi_cascade *c, int d) {
  const gi_level *L = &c->lv[d];
  uint32_t need = 0;
  if (d < 1 || !L->has_inner) return 0;
  FOR_NESTED(L, i, j, k) need += L->vix[gi__slot(i, j, k, c->R)] == 0 && nested_any(&c->lv[d - 1], c->R, i, j, k);
  return need;
}

/* Takes and gives back the nested cells' entries (room for `need` reserved). */
static void nested_assign(struct gi_cascade *c, int d) {
  gi_level *L = &c->lv[d];
  int R = c->R;
  if (d < 1 || !L->has_inner) return;
  FOR_NESTED(L, i, j, k) {
    uint32_t slot = gi__slot(i, j, k, R);
    int any = nested_any(&c->lv[d - 1], R, i, j, k);
    if (any && L->vix[slot] == 0) gi__level_take(L, slot);
    else if (!any && L->vix[slot] != 0) gi__level_release(L, slot);
  }
}

gi_result gi__nested_entries(struct gi_cascade *c, int d, gi_error_info *err) {
  gi_level *L = &c->lv[d];
  uint32_t need = gi__nested_need(c, d), room = gi__level_free_entries(L);
  if (need > room) {
    gi_result rc = gi__level_reserve(c, d, L->cap + need - room, 1, err);
    if (rc != GI_OK) return rc;
  }
  nested_assign(c, d);
  return GI_OK;
}

/* One level's triangles over its window, found and binned by bin_level
 * (levels run in parallel, each with its own list and error). */
typedef struct {
  uint32_t *tris;
  size_t ntris, cap;
  uint64_t kept;     /* triangles binned: the report's triangles_visited */
  gi_result rc;
  gi_error_info err;
} level_list;

/* The voxelization's buffers: each level's triangle list and bins, the
 * workers' scratch and every task's output. */
typedef struct {
  level_list list[GI_MAX_LEVELS];
  uint32_t *bin_tris[GI_MAX_LEVELS], *bin_start[GI_MAX_LEVELS];
  int nslab;
  gi_vgeo **scratch; /* per worker */
  slab_out *out;     /* per task: level * nslab * BANDS + slab * BANDS + band */
} vox_bufs;

/* A window that holds the scene's bounds overlaps every triangle: the
 * coarse levels of a small scene need no BVH query. */
static int holds_scene(const gi_level *L, const gi_scene *s) {
  for (int a = 0; a < 3; a++)
    if (!(L->lo[a] <= s->lo[a] && s->hi[a] <= L->hi[a])) return 0;
  return 1;
}

/* Every triangle, in index order. */
static gi_result all_tris(const gi_scene *s, level_list *b) {
  size_t n = s->num_triangles;
  if (b->cap < n) {
    uint32_t *t = gi__realloc(b->tris, (n + 1) * sizeof *t);
    if (!t) return GI_ERR_NOMEM;
    b->tris = t;
    b->cap = n + 1;
  }
  for (size_t q = 0; q < n; q++) b->tris[q] = (uint32_t)q;
  b->ntris = n;
  return GI_OK;
}

/* The window cells [*c0, *c1] (from its first, clamped) that a triangle
 * spanning [lo, hi] on axis a touches; 0 when it misses the window. */
static int cell_span(const gi_level *L, int R, int a, float lo, float hi, int64_t *c0, int64_t *c1) {
  *c0 = (int64_t)floor((double)lo / L->s) - L->cell0[a];
  *c1 = (int64_t)floor((double)hi / L->s) - L->cell0[a];
  if (*c1 < 0 || *c0 >= R) return 0;
  if (*c0 < 0) *c0 = 0;
  if (*c1 >= R) *c1 = R - 1;
  return 1;
}

/* The triangles over level d's window, but those wholly inside the finer
 * level's region, binned into tasks: z-slabs and y-bands. Levels run
 * side by side (voxelize_levels); each writes only its own list and bins. */
static gi_result bin_level(const struct gi_cascade *c, int d, vox_bufs *vb, gi_error_info *err) {
  const gi_scene *s = c->scene;
  int R = c->R, nslab = vb->nslab;
  gi_result rc = GI_OK;
  const gi_level *L = &c->lv[d];
  level_list *b = &vb->list[d];
  /* Querying and binning a level is one task: check around it. */
  if (gi_cancel_check(c->cancel) != GI_CANCEL_NONE) return gi__cancel_fail(c->cancel, err, "voxelize");
  b->ntris = 0;
  if (s->rtc && holds_scene(L, s)) {
    rc = all_tris(s, b);
    if (rc != GI_OK) return gi__fail(err, rc, "voxelize: out of memory listing the triangles of level %d", d);
  } else if (s->rtc) {
    rc = gi__query_box(s, L->lo, L->hi, &b->tris, &b->ntris, &b->cap);
    if (rc != GI_OK) return gi__fail(err, rc, "voxelize: BVH query failed for level %d", d);
    gi__order_tris(s, b->tris, &b->ntris);
  }
  if (gi_cancel_check(c->cancel) != GI_CANCEL_NONE) return gi__cancel_fail(c->cancel, err, "voxelize");
  /* Drop triangles wholly inside the finer level's region. */
  size_t kept = 0;
  float ilo[3] = {0}, ihi[3] = {0};
  if (L->has_inner)
    for (int a = 0; a < 3; a++) {
      ilo[a] = (float)(L->inner0[a] * L->s);
      ihi[a] = (float)(L->inner1[a] * L->s);
    }
  int nbin = nslab * BANDS, RB = R / BANDS;
  memset(vb->bin_start[d], 0, ((size_t)nbin + 1) * sizeof *vb->bin_start[d]);
  for (size_t q = 0; q < b->ntris; q++) {
    if (q % GI_CANCEL_EVERY_TRIS == 0 && gi_cancel_check(c->cancel) != GI_CANCEL_NONE)
      return gi__cancel_fail(c->cancel, err, "voxelize");
    const uint32_t *ix = &s->indices[3 * b->tris[q]];
    float lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
      float x0 = s->vertices[3 * ix[0] + a], x1 = s->vertices[3 * ix[1] + a], x2 = s->vertices[3 * ix[2] + a];
      lo[a] = gi__minf(x0, gi__minf(x1, x2));
      hi[a] = gi__maxf(x0, gi__maxf(x1, x2));
    }
    if (L->has_inner && lo[0] > ilo[0] && hi[0] < ihi[0] && lo[1] > ilo[1] && hi[1] < ihi[1] &&
        lo[2] > ilo[2] && hi[2] < ihi[2])
      continue;
    int64_t k0, k1, y0, y1;
    if (!cell_span(L, R, 2, lo[2], hi[2], &k0, &k1)) continue;
    b->tris[kept++] = b->tris[q];
    if (!cell_span(L, R, 1, lo[1], hi[1], &y0, &y1)) continue; /* counted, but over no cell */
    for (int64_t sl = k0 / SLAB; sl <= k1 / SLAB; sl++)
      for (int64_t bd = y0 / RB; bd <= y1 / RB; bd++) vb->bin_start[d][sl * BANDS + bd + 1]++;
  }
  b->kept = kept;
  for (int t = 0; t < nbin; t++) vb->bin_start[d][t + 1] += vb->bin_start[d][t];
  gi__free(vb->bin_tris[d]);
  vb->bin_tris[d] = gi__malloc(((size_t)vb->bin_start[d][nbin] + 1) * sizeof *vb->bin_tris[d]);
  uint32_t *fill = gi__malloc(((size_t)nbin + 1) * sizeof *fill);
  if (!vb->bin_tris[d] || !fill) {
    gi__free(fill);
    return gi__fail(err, GI_ERR_NOMEM, "voxelize: out of memory binning level %d", d);
  }
  memcpy(fill, vb->bin_start[d], ((size_t)nbin + 1) * sizeof *fill);
  for (size_t q = 0; q < kept; q++) {
    const uint32_t *ix = &s->indices[3 * b->tris[q]];
    float lo[3], hi[3];
    for (int a = 1; a < 3; a++) {
      float x0 = s->vertices[3 * ix[0] + a], x1 = s->vertices[3 * ix[1] + a], x2 = s->vertices[3 * ix[2] + a];
      lo[a] = gi__minf(x0, gi__minf(x1, x2));
      hi[a] = gi__maxf(x0, gi__maxf(x1, x2));
    }
    int64_t k0, k1, y0, y1;
    cell_span(L, R, 2, lo[2], hi[2], &k0, &k1);
    if (!cell_span(L, R, 1, lo[1], hi[1], &y0, &y1)) continue;
    for (int64_t sl = k0 / SLAB; sl <= k1 / SLAB; sl++)
      for (int64_t bd = y0 / RB; bd <= y1 / RB; bd++) vb->bin_tris[d][fill[sl * BANDS + bd]++] = b->tris[q];
  }
  gi__free(fill);
  return GI_OK;
}

/* Voxelizes every level: each level's triangles binned (serial), every
 * level's tasks in one parallel loop, then each level's entries in the
 * bake's order, finest first (a level's nested cells read the finer
 * level's entries). */
typedef struct {
  const struct gi_cascade *c;
  vox_bufs *b;
} bin_ctx;

/* Levels coarsest first: the coarsest holds the most triangles (the 5 km
 * city's: 3 of its 3.3 million, 180 of the 300 ms its levels' queries
 * and binning took one after another), so it starts at once. */
static void bin_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  bin_ctx *x = p;
  for (size_t q = b; q < e; q++) {
    int d = x->c->n - 1 - (int)q;
    x->b->list[d].rc = bin_level(x->c, d, x->b, &x->b->list[d].err);
  }
}

static gi_result voxelize_levels(struct gi_cascade *c, int threads, vox_bufs *b, gi_error_info *err) {
  gi_result rc = GI_OK;
  vox_ctx v = {.c = c, .per_level = (size_t)b->nslab * BANDS, .scratch = b->scratch, .out = b->out};
  for (int d = 0; d < c->n; d++) b->list[d].rc = GI_ERR_CANCELLED;
  bin_ctx bx = {.c = c, .b = b};
  int stopped = gi__parallel_for_cancel((size_t)c->n, 1, threads, bin_range, &bx, NULL, c->cancel);
  for (int d = 0; d < c->n; d++) {
    level_list *l = &b->list[d];
    if (l->rc == GI_ERR_CANCELLED || (stopped && l->rc == GI_OK)) return gi__cancel_fail(c->cancel, err, "voxelize");
    if (l->rc != GI_OK) {
      if (err) *err = l->err;
      return l->rc;
    }
    c->report.triangles_visited += l->kept;
    v.bin_start[d] = b->bin_start[d], v.bin_tris[d] = b->bin_tris[d];
  }
  atomic_init(&v.failed, 0);
  int cancelled = gi__parallel_for_cancel((size_t)c->n * v.per_level, 1, threads, voxelize_slabs, &v, &v.failed,
                                          c->cancel);
  if (atomic_load(&v.failed)) return gi__fail(err, GI_ERR_NOMEM, "voxelize: out of memory");
  if (cancelled) return gi__cancel_fail(c->cancel, err, "voxelize");
  for (int d = 0; d < c->n; d++) {
    if ((rc = gather_slabs(c, d, b->out + d * v.per_level, b->nslab, gi__nested_need(c, d), err)) != GI_OK) return rc;
    nested_assign(c, d);
    c->report.occupied[d] = c->lv[d].num_geo;
  }
  fill_ctx fx = {.c = c, .out = b->out, .per_level = v.per_level};
  gi__parallel_for((size_t)c->n * v.per_level, 4, threads, fill_entries, &fx);
  return GI_OK;
}

gi_result gi__voxelize(struct gi_cascade *c, int threads, gi_error_info *err) {
  int R = c->R;
  vox_bufs b = {.nslab = (R + SLAB - 1) / SLAB};
  size_t tasks = (size_t)c->n * b.nslab * BANDS;
  int nw = gi__num_workers(threads);
  gi_result rc = GI_OK;
  for (int d = 0; d < c->n && rc == GI_OK; d++)
    if (!(b.bin_start[d] = gi__calloc((size_t)b.nslab * BANDS + 1, sizeof *b.bin_start[d])))
      rc = gi__fail(err, GI_ERR_NOMEM, "voxelize: out of memory");
  b.scratch = gi__calloc((size_t)nw, sizeof *b.scratch);
  b.out = gi__calloc(tasks, sizeof *b.out);
  if (!b.scratch || !b.out) rc = gi__fail(err, GI_ERR_NOMEM, "voxelize: out of memory");
  for (int w = 0; w < nw && rc == GI_OK; w++)
    if (!(b.scratch[w] = gi__malloc((size_t)SLAB * (R / BANDS) * R * sizeof **b.scratch)))
      rc = gi__fail(err, GI_ERR_NOMEM, "voxelize: out of memory");
  if (rc == GI_OK) rc = voxelize_levels(c, threads, &b, err);
  for (size_t t = 0; b.out && t < tasks; t++) gi__free(b.out[t].slot), gi__free(b.out[t].geo);
  for (int w = 0; b.scratch && w < nw; w++) gi__free(b.scratch[w]);
  for (int d = 0; d < c->n; d++) gi__free(b.bin_tris[d]), gi__free(b.bin_start[d]), gi__free(b.list[d].tris);
  gi__free(b.out);
  gi__free(b.scratch);
  return rc;
}
