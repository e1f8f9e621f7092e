/* light_tree.c: emissive triangles picked by power and distance.
 *
 * A city has thousands of small emitters (windows, signs). Picking them by
 * power alone gives a point near one window the same chance of sampling it
 * as any window across town, so a few rare samples carry most of the light:
 * noisy, and a probe jumps whenever one of them turns visible. The tree is
 * a binary hierarchy of the emitters (median splits along the widest
 * centroid axis); a sample walks down from the root choosing each child
 * with probability proportional to its importance seen from the point,
 * power / max(distance to its box centre^2, half its diagonal^2), times
 * how far its emitters can face the point (a cone bounding their normals,
 * widened by the angle the box subtends: most emitters are one-sided). The
 * importance is continuous in the point, so with the same random numbers
 * the choice changes little as the point moves. The probability of any
 * emitter is the product of the choices on its path, recomputed from its
 * leaf upward for multiple importance sampling. Built once with the scene,
 * read-only afterwards. */
#include <float.h>
#include <math.h>
#include <string.h>
#include <emmintrin.h>
#include "base/internal.h"
#include "scene/lights.h"

#define GI_LT_PI 3.14159265358979323846

typedef struct build_ctx {
  gi_scene *s;
  uint32_t *slots;   /* emitter slots, permuted by the splits */
  float *centroid;   /* 3 per slot */
  const float *power;/* per slot */
  uint32_t next;     /* next free node */
} build_ctx;

static void tri_bounds(const gi_scene *s, uint32_t tri, float lo[3], float hi[3]) {
  const uint32_t *ix = &s->indices[3 * tri];
  for (int k = 0; k < 3; k++) lo[k] = FLT_MAX, hi[k] = -FLT_MAX;
  for (int v = 0; v < 3; v++)
    for (int k = 0; k < 3; k++) {
      float x = s->vertices[3 * ix[v] + k];
      lo[k] = gi__minf(lo[k], x), hi[k] = gi__maxf(hi[k], x);
    }
}

/* The cone of normals of one emitter: its winding normal, or every
 * direction for a two-sided one. */
static void leaf_cone(const gi_scene *s, uint32_t tri, gi_light_node *n) {
  float ng[3];
  gi__tri_cross(s, tri, ng);
  float l = gi__len(ng);
  for (int k = 0; k < 3; k++) n->axis[k] = l > 0 ? ng[k] / l : (k == 0);
  n->cos_o = l > 0 && !s->materials[s->tri_material[tri]].two_sided ? 1.f : -1.f, n->sin_o = 0.f;
}

/* The smallest cone (of this construction) holding the cones of a and b. */
static void merge_cones(const gi_light_node *a, const gi_light_node *b, gi_light_node *out) {
  double ta = acos(fmax(-1.0, fmin(1.0, a->cos_o))), tb = acos(fmax(-1.0, fmin(1.0, b->cos_o)));
  if (ta < tb) {
    const gi_light_node *t = a;
    a = b, b = t;
    double x = ta;
    ta = tb, tb = x;
  }
  double dot = 0;
  for (int k = 0; k < 3; k++) dot += (double)a->axis[k] * b->axis[k];
  double td = acos(fmax(-1.0, fmin(1.0, dot)));
  memcpy(out->axis, a->axis, sizeof out->axis);
  double to = ta;
  if (fmin(td + tb, GI_LT_PI) > ta) {
    to = 0.5 * (ta + td + tb);
    if (to >= GI_LT_PI || td < 1e-6) {
      to = to >= GI_LT_PI ? GI_LT_PI : to;
    } else {
      /* Turn a's axis toward b's by to - ta. */
      double tr = to - ta, sd = sin(td);
      double ca = sin(td - tr) / sd, cb = sin(tr) / sd, l = 0;
      for (int k = 0; k < 3; k++) {
        out->axis[k] = (float)(ca * a->axis[k] + cb * b->axis[k]);
        l += (double)out->axis[k] * out->axis[k];
      }
      l = sqrt(l);
      for (int k = 0; k < 3; k++) out->axis[k] = l > 0 ? (float)(out->axis[k] / l) : a->axis[k];
    }
  }
  out->cos_o = (float)cos(to), out->sin_o = (float)sin(to);
  if (to >= GI_LT_PI) out->cos_o = -1.f, out->sin_o = 0.f;
}

/* Reorders slots[b..e) so that the one of rank m along axis sits at m,
 * smaller centroids before it and larger after (quickselect). */
static void select_median(build_ctx *c, uint32_t b, uint32_t e, uint32_t m, int axis) {
  uint32_t *a = c->slots;
  int64_t lo = b, hi = (int64_t)e - 1;
  while (hi > lo) {
    float pivot = c->centroid[3 * a[lo + (hi - lo) / 2] + axis];
    int64_t i = lo, j = hi;
    while (i <= j) {
      while (c->centroid[3 * a[i] + axis] < pivot) i++;
      while (c->centroid[3 * a[j] + axis] > pivot) j--;
      if (i <= j) {
        uint32_t t = a[i];
        a[i++] = a[j], a[j--] = t;
      }
    }
    /* Now [lo, j] <= pivot <= [i, hi], and anything between equals it. */
    if ((int64_t)m <= j) hi = j;
    else if ((int64_t)m >= i) lo = i;
    else return;
  }
}

/* Node n over slots[b..e): its box, power and children (depth-first, so
 * the tree is as deep as log2 of the emitter count). Bounds take the
 * inline min and max (vertices are finite): fminf and fmaxf are libm
 * calls here, 7% of building the city. */
static void build_node(build_ctx *c, uint32_t n, uint32_t parent, uint32_t b, uint32_t e) {
  gi_light_node *nd = &c->s->ltree[n];
  nd->parent = parent;
  float clo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, chi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
  double pw = 0;
  for (int k = 0; k < 3; k++) nd->lo[k] = FLT_MAX, nd->hi[k] = -FLT_MAX;
  for (uint32_t i = b; i < e; i++) {
    uint32_t sl = c->slots[i];
    float lo[3], hi[3];
    tri_bounds(c->s, c->s->emitter_tri[sl], lo, hi);
    for (int k = 0; k < 3; k++) {
      nd->lo[k] = gi__minf(nd->lo[k], lo[k]), nd->hi[k] = gi__maxf(nd->hi[k], hi[k]);
      clo[k] = gi__minf(clo[k], c->centroid[3 * sl + k]), chi[k] = gi__maxf(chi[k], c->centroid[3 * sl + k]);
    }
    pw += c->power[sl];
  }
  nd->power = (float)pw;
  if (e - b == 1) {
    nd->slot = c->slots[b];
    nd->child = 0;
    c->s->emitter_leaf[nd->slot] = n;
    leaf_cone(c->s, c->s->emitter_tri[nd->slot], nd);
    return;
  }
  int axis = 0;
  for (int k = 1; k < 3; k++)
    if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
  uint32_t m = b + (e - b) / 2;
  select_median(c, b, e, m, axis);
  nd->slot = UINT32_MAX;
  nd->child = c->next;
  c->next += 2;
  uint32_t l = nd->child;
  build_node(c, l, n, b, m);
  build_node(c, l + 1, n, m, e);
  merge_cones(&c->s->ltree[l], &c->s->ltree[l + 1], &c->s->ltree[n]);
}

/* Each internal node's children into its pair (gi_light_pair). */
static void fill_pairs(gi_scene *s) {
  for (uint32_t n = 0; n < s->num_lnodes; n++) {
    const gi_light_node *nd = &s->ltree[n];
    if (nd->slot != UINT32_MAX) continue;
    gi_light_pair *q = &s->lpair[(nd->child - 1) / 2];
    for (int i = 0; i < 2; i++) {
      const gi_light_node *m = &s->ltree[nd->child + i];
      float h2 = 0;
      for (int k = 0; k < 3; k++) {
        float h = 0.5f * (m->hi[k] - m->lo[k]);
        q->cen[k][i] = 0.5f * (m->lo[k] + m->hi[k]);
        q->axis[k][i] = m->axis[k];
        h2 += h * h;
      }
      q->h2[i] = h2, q->h[i] = sqrtf(h2);
      q->power[i] = m->power, q->cos_o[i] = m->cos_o, q->sin_o[i] = m->sin_o;
      q->link[i] = m->slot != UINT32_MAX ? GI_LT_LEAF | m->slot : (m->child - 1) / 2;
    }
  }
}

gi_result gi__light_tree_build(gi_scene *s, const float *power, gi_error_info *err) {
  uint32_t ne = s->num_emitters;
  if (!ne) return GI_OK;
  /* A pair's link keeps a leaf's slot below its flag bit. */
  if (ne >= GI_LT_LEAF) return gi__fail(err, GI_ERR_LIMIT, "light tree: %u emitters, at most %u", ne, GI_LT_LEAF - 1);
  build_ctx c = {.s = s, .power = power, .next = 1};
  s->ltree = gi__malloc((2 * (size_t)ne - 1) * sizeof *s->ltree);
  s->emitter_leaf = gi__malloc(ne * sizeof *s->emitter_leaf);
  s->lpair = gi__malloc((ne > 1 ? ne - 1 : 1) * sizeof *s->lpair);
  s->emitter_geo = gi__malloc(ne * sizeof *s->emitter_geo);
  c.slots = gi__malloc(ne * sizeof *c.slots);
  c.centroid = gi__malloc(3 * (size_t)ne * sizeof *c.centroid);
  gi_result rc = GI_OK;
  if (!s->ltree || !s->emitter_leaf || !s->lpair || !s->emitter_geo || !c.slots || !c.centroid) {
    rc = gi__fail(err, GI_ERR_NOMEM, "out of memory for the light tree of %u emitters", ne);
    goto done;
  }
  for (uint32_t i = 0; i < ne; i++) {
    const uint32_t *ix = &s->indices[3 * s->emitter_tri[i]];
    gi_emitter_geo *eg = &s->emitter_geo[i];
    for (int v = 0; v < 3; v++) memcpy(eg->v[v], &s->vertices[3 * ix[v]], sizeof eg->v[v]);
    memcpy(eg->Le, s->materials[s->tri_material[s->emitter_tri[i]]].emission, sizeof eg->Le);
    eg->two_sided = s->materials[s->tri_material[s->emitter_tri[i]]].two_sided != 0;
    for (int k = 0; k < 3; k++)
      c.centroid[3 * i + k] =
          (s->vertices[3 * ix[0] + k] + s->vertices[3 * ix[1] + k] + s->vertices[3 * ix[2] + k]) / 3.f;
    c.slots[i] = i;
  }
  build_node(&c, 0, UINT32_MAX, 0, ne);
  s->num_lnodes = c.next;
  fill_pairs(s);
done:
  gi__free(c.slots);
  gi__free(c.centroid);
  return rc;
}

/* max for values that are never NaN here: fmaxf is a libm call unless
 * the compiler may assume no NaN (it was 1.5% of the city's bake). */
static inline float maxf(float a, float b) { return a > b ? a : b; }

/* Where point p lies from node n's box: v from the box's centre, its
 * squared length d2 and the box's squared half-diagonal h2. */
static void node_offset(const gi_light_node *n, const float p[3], float v[3], float *d2, float *h2) {
  *d2 = *h2 = 0;
  for (int k = 0; k < 3; k++) {
    float h = 0.5f * (n->hi[k] - n->lo[k]);
    v[k] = p[k] - 0.5f * (n->lo[k] + n->hi[k]);
    *d2 += v[k] * v[k], *h2 += h * h;
  }
}

/* The cosine of the smallest angle at which one of n's emitters could face
 * p (offset v, d2, h2 from node_offset): 1 when one may face it head-on
 * (or p is inside the box's sphere), <= 0 when none faces it. */
static float facing_cos(const gi_light_node *n, const float v[3], float d2, float h2) {
  if (n->cos_o <= -1.f || d2 <= h2) return 1.f; /* faces everywhere, or p is inside the box */
  float d = sqrtf(d2);
  float cos_t = (v[0] * n->axis[0] + v[1] * n->axis[1] + v[2] * n->axis[2]) / d;
  float sin_t = sqrtf(maxf(0.f, 1 - cos_t * cos_t));
  float sin_u = sqrtf(h2) / d, cos_u = sqrtf(maxf(0.f, 1 - sin_u * sin_u));
  /* theta_o + theta_u: the cone widened by the box's angular radius. */
  float cos_s = n->cos_o * cos_u - n->sin_o * sin_u, sin_s = n->sin_o * cos_u + n->cos_o * sin_u;
  if (sin_s < 0 || cos_t >= cos_s) return 1.f; /* the widened cone covers p's direction */
  return cos_t * cos_s + sin_t * sin_s;         /* cos(theta - theta_o - theta_u) */
}

/* Whether node n's box reaches past plane (o, nrm) on nrm's side. */
static int node_ahead(const gi_light_node *n, const float *o, const float *nrm) {
  float ahead = 0;
  for (int k = 0; k < 3; k++) ahead += nrm[k] * ((nrm[k] > 0 ? n->hi[k] : n->lo[k]) - o[k]);
  return ahead > 0;
}

/* Whether some emitter under node n may lie in front of plane (o, nrm)
 * and show o its front: the box reaches past the plane, and the facing
 * bound admits o. Conservative: 1 when unsure. */
static int node_may_face(const gi_light_node *n, const float *o, const float *nrm) {
  float v[3], d2, h2;
  if (!node_ahead(n, o, nrm)) return 0;
  node_offset(n, o, v, &d2, &h2);
  /* A small margin: float rounding must not hide a grazing emitter. */
  return facing_cos(n, v, d2, h2) > -1e-4f;
}

/* Whether some leaf under the root passes `keep` (which a node must pass
 * for any leaf under it to): a depth-first walk of at most
 * GI_LT_FACE_BUDGET nodes, 1 (may) when that is not enough to tell. */
static inline int any_leaf(const gi_scene *s, int (*keep)(const gi_light_node *, const float *, const float *),
                           const float *a, const float *b) {
  if (s->num_lnodes == 0) return 0;
  uint32_t stack[GI_LT_FACE_BUDGET];
  int top = 0, visits = 0;
  stack[top++] = 0;
  while (top > 0) {
    const gi_light_node *n = &s->ltree[stack[--top]];
    if (++visits > GI_LT_FACE_BUDGET) return 1;
    if (!keep(n, a, b)) continue;
    if (n->slot != UINT32_MAX) return 1;
    if (top + 2 > GI_LT_FACE_BUDGET) return 1;
    stack[top++] = n->child;
    stack[top++] = n->child + 1;
  }
  return 0;
}

int gi__light_tree_may_face(const gi_scene *s, const float o[3], const float nrm[3]) {
  return any_leaf(s, node_may_face, o, nrm);
}

/* Node n's box within distance *r of p. */
static int node_within(const gi_light_node *n, const float *p, const float *r) {
  float d2 = 0;
  for (int k = 0; k < 3; k++) {
    float e = p[k] < n->lo[k] ? n->lo[k] - p[k] : p[k] > n->hi[k] ? p[k] - n->hi[k] : 0.f;
    d2 += e * e;
  }
  return d2 <= *r * *r;
}

int gi__light_tree_within(const gi_scene *s, const float p[3], float r) { return any_leaf(s, node_within, p, &r); }

int gi__light_tree_ahead(const gi_scene *s, const float o[3], const float nrm[3]) {
  return any_leaf(s, node_ahead, o, nrm);
}

/* The two floats of a pair's field in lanes 0 and 1 (2 and 3: zero). */
static inline __m128 load2(const float v[2]) {
  return _mm_loadl_pi(_mm_setzero_ps(), (const __m64 *)v);
}

/* How much each child of pair qa (lanes 0 and 1) and of pair qb (lanes 2
 * and 3; NULL: zeros, dropped) matters to point p: power over squared
 * distance, times the cosine of the smallest angle at which one of its
 * emitters could face p (facing_cos; 0 when none can). Continuous in p,
 * and without trigonometry. Lane by lane, by the operations facing_cos
 * and node_offset make, in their order (no fused multiply-add in this
 * build), so a pair weighs the same in either half and alone. The picks
 * of a city bake and 3000 probes took 1.5x less CPU than a child at a
 * time (perf, 523 -> 341 ms). */
static inline __m128 load4(const float a[2], const float *b) {
  __m128 lo = load2(a);
  return b ? _mm_loadh_pi(lo, (const __m64 *)b) : lo;
}

static void pairs_importance(const gi_light_pair *qa, const gi_light_pair *qb, const float p[3], float out[4]) {
#define GI_LT_F(f) load4(qa->f, qb ? qb->f : NULL)
  __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.f);
  __m128 vx = _mm_sub_ps(_mm_set1_ps(p[0]), GI_LT_F(cen[0]));
  __m128 vy = _mm_sub_ps(_mm_set1_ps(p[1]), GI_LT_F(cen[1]));
  __m128 vz = _mm_sub_ps(_mm_set1_ps(p[2]), GI_LT_F(cen[2]));
  __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(vx, vx), _mm_mul_ps(vy, vy)), _mm_mul_ps(vz, vz));
  __m128 h2 = GI_LT_F(h2), cos_o = GI_LT_F(cos_o), sin_o = GI_LT_F(sin_o);
  /* maxf(a, b) is a > b ? a : b, which is what maxps returns. */
  __m128 base = _mm_div_ps(GI_LT_F(power), _mm_max_ps(_mm_max_ps(d2, h2), _mm_set1_ps(FLT_MIN)));
  __m128 d = _mm_sqrt_ps(d2);
  __m128 dot = _mm_add_ps(_mm_add_ps(_mm_mul_ps(vx, GI_LT_F(axis[0])), _mm_mul_ps(vy, GI_LT_F(axis[1]))),
                          _mm_mul_ps(vz, GI_LT_F(axis[2])));
  __m128 cos_t = _mm_div_ps(dot, d);
  __m128 sin_t = _mm_sqrt_ps(_mm_max_ps(zero, _mm_sub_ps(one, _mm_mul_ps(cos_t, cos_t))));
  __m128 sin_u = _mm_div_ps(GI_LT_F(h), d);
  __m128 cos_u = _mm_sqrt_ps(_mm_max_ps(zero, _mm_sub_ps(one, _mm_mul_ps(sin_u, sin_u))));
  __m128 cos_s = _mm_sub_ps(_mm_mul_ps(cos_o, cos_u), _mm_mul_ps(sin_o, sin_u));
  __m128 sin_s = _mm_add_ps(_mm_mul_ps(sin_o, cos_u), _mm_mul_ps(cos_o, sin_u));
  __m128 cosp = _mm_add_ps(_mm_mul_ps(cos_t, cos_s), _mm_mul_ps(sin_t, sin_s));
  /* facing_cos's early answers of 1: any direction, p inside, or covered. */
  __m128 full = _mm_or_ps(_mm_or_ps(_mm_cmple_ps(cos_o, _mm_set1_ps(-1.f)), _mm_cmple_ps(d2, h2)),
                          _mm_or_ps(_mm_cmplt_ps(sin_s, zero), _mm_cmpge_ps(cos_t, cos_s)));
  cosp = _mm_or_ps(_mm_and_ps(full, one), _mm_andnot_ps(full, cosp));
  _mm_storeu_ps(out, _mm_and_ps(_mm_cmpgt_ps(cosp, zero), _mm_mul_ps(base, cosp)));
#undef GI_LT_F
}

/* The left child's probability from two children's importance. */
static inline double left_of(float il, float ir) {
  return (double)il + (double)ir > 0 ? (double)il / ((double)il + (double)ir) : 0.5;
}

/* Probability of taking the left child of the node whose children are pair q. */
static double left_prob(const gi_light_pair *q, const float p[3]) {
  float imp[4];
  pairs_importance(q, NULL, p, imp);
  return left_of(imp[0], imp[1]);
}

/* The link of the tree's root (a leaf when there is one emitter). */
static inline uint32_t root_link(const gi_scene *s) {
  return s->ltree[0].slot != UINT32_MAX ? GI_LT_LEAF | s->ltree[0].slot : 0;
}

/* One step down from the node whose children are pair q, taking the left
 * child with probability l: returns the child's link, rescales *u within
 * the branch taken and multiplies *pr by its probability. */
static inline uint32_t step_down(const gi_light_pair *q, double l, double *u, double *pr) {
  /* Either branch's numbers chosen by a mask, not a jump (the compiler
   * jumps on a plain ?:): which way u goes is a coin toss per pick and
   * level, and the mispredicted branch cost the picks more than the
   * division both ways share. The same operations on the same numbers. */
  __m128d vu = _mm_set_sd(*u), vl = _mm_set_sd(l), left = _mm_cmplt_sd(vu, vl);
  __m128d num = _mm_or_pd(_mm_and_pd(left, vu), _mm_andnot_pd(left, _mm_sub_sd(vu, vl)));
  __m128d den = _mm_or_pd(_mm_and_pd(left, vl), _mm_andnot_pd(left, _mm_sub_sd(_mm_set_sd(1.0), vl)));
  double r = _mm_cvtsd_f64(_mm_div_sd(num, den));
  *pr *= _mm_cvtsd_f64(den);
  *u = r < 0 ? 0 : r >= 1 ? 0x1.fffffffffffffp-1 : r;
  return q->link[_mm_movemask_pd(left) & 1 ? 0 : 1];
}

uint32_t gi__light_tree_pick(const gi_scene *s, const float p[3], double u, float *prob, float *u_rest) {
  double pr = 1;
  uint32_t link = root_link(s);
  while (!(link & GI_LT_LEAF)) {
    const gi_light_pair *q = &s->lpair[link];
    link = step_down(q, left_prob(q, p), &u, &pr);
  }
  *prob = (float)pr;
  *u_rest = (float)u;
  return link & ~GI_LT_LEAF;
}

/* Picks per batch of gi__light_tree_picks (its buffers live on the stack). */
enum { PICK_BATCH = 64 };

/* One batch of gi__light_tree_picks: n <= PICK_BATCH picks. */
static void picks_batch(const gi_scene *s, const float p[3], const double *u, int n, gi_emitter_pick *out) {
  uint32_t link[PICK_BATCH];
  double uu[PICK_BATCH], pr[PICK_BATCH], pl[PICK_BATCH];
  int live[PICK_BATCH], head[PICK_BATCH], nl = 0;
  uint32_t root = root_link(s);
  for (int k = 0; k < n; k++) {
    link[k] = root, uu[k] = u[k], pr[k] = 1;
    if (!(root & GI_LT_LEAF)) live[nl++] = k;
  }
  while (nl > 0) {
    /* The picks at one node are neighbours in u: weigh each node once. */
    int nh = 0;
    for (int i = 0; i < nl; i++)
      if (i == 0 || link[live[i]] != link[live[i - 1]]) head[nh++] = i;
    for (int j = 0; j < nh; j += 2) {
      float imp[4];
      const gi_light_pair *qb = j + 1 < nh ? &s->lpair[link[live[head[j + 1]]]] : NULL;
      pairs_importance(&s->lpair[link[live[head[j]]]], qb, p, imp);
      pl[head[j]] = left_of(imp[0], imp[1]);
      if (qb) pl[head[j + 1]] = left_of(imp[2], imp[3]);
    }
    /* Each pick one step down, as gi__light_tree_pick steps. */
    int nn = 0;
    double l = 0.5;
    uint32_t at = UINT32_MAX; /* the node whose weight l is */
    for (int i = 0; i < nl; i++) {
      int k = live[i];
      if (link[k] != at) at = link[k], l = pl[i];
      link[k] = step_down(&s->lpair[link[k]], l, &uu[k], &pr[k]);
      if (!(link[k] & GI_LT_LEAF)) live[nn++] = k;
    }
    nl = nn;
  }
  for (int k = 0; k < n; k++) {
    out[k].slot = link[k] & ~GI_LT_LEAF;
    out[k].prob = (float)pr[k];
    out[k].u_rest = (float)uu[k];
  }
}

void gi__light_tree_picks(const gi_scene *s, const float p[3], const double *u, int m, gi_emitter_pick *out) {
  for (int b = 0; b < m; b += PICK_BATCH) picks_batch(s, p, u + b, m - b < PICK_BATCH ? m - b : PICK_BATCH, out + b);
}

float gi__light_tree_prob(const gi_scene *s, const float p[3], uint32_t slot) {
  uint32_t at = s->emitter_leaf[slot];
  double pr = 1;
  while (s->ltree[at].parent != UINT32_MAX) {
    const gi_light_node *par = &s->ltree[s->ltree[at].parent];
    double pl = left_prob(&s->lpair[(par->child - 1) / 2], p);
    pr *= at == par->child ? pl : 1 - pl;
    at = s->ltree[at].parent;
  }
  return (float)pr;
}
