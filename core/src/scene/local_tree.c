/* local_tree.c: point and spot light samples, through a light cut when a scene has many.
 *
 * With a few hundred lights every point samples every light, one shadow
 * ray each (lights.h says where the line is). A city of street lamps has
 * thousands: each voxel, probe and pixel then paid one sample per lamp
 * (16,384 lamps: 1.46 s of injection, 0.5 ms per probe), and a lamp
 * across town brings next to nothing. The lights are kept in a binary
 * tree (median splits along the widest axis of their positions; a node
 * holds its lights' box and summed intensity). Per point, a light cut in
 * the manner of Lightcuts (Walter et al. 2005): starting from the root,
 * the node that could bring the most, intensity / squared distance to its
 * box, is split into its children until every node left could bring at
 * most GI_LOCAL_CUT_SHARE of the cut's estimated total, or the cut is
 * full (the plan's local_cut, lights.h). A leaf of the cut is its light's
 * own sample. A node is one light picked inside it, walking down with
 * probability proportional to each child's intensity over its squared
 * distance, and divided by that probability: the sum stays unbiased, and
 * only nodes that bring little are sampled. Spot cones are left out of the bounds
 * (a spot aimed away is a sample of zero). Built once with the scene,
 * read-only afterwards: thread-safe. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "scene/lights.h"

/* One sample per light (every light of a scene with few; the cut's picks). */
int gi__local_sample(const gi_scene *s, const gi_light *l, const float p[3], gi_lsample *o) {
  float v[3];
  for (int k = 0; k < 3; k++) v[k] = (float)(l->position[k] - s->origin[k]) - p[k];
  float r2 = gi__dot(v, v);
  if (!(r2 > 1e-12f)) return 0;
  float r = sqrtf(r2);
  for (int k = 0; k < 3; k++) o->w[k] = v[k] / r;
  float f = 1.0f;
  if (l->type == GI_LIGHT_SPOT) {
    float c = -gi__dot(o->w, l->direction);
    if (c <= l->cos_outer) return 0;
    if (c < l->cos_inner) {
      float t = (c - l->cos_outer) / fmaxf(l->cos_inner - l->cos_outer, 1e-6f);
      f = t * t * (3 - 2 * t);
    }
  }
  o->dist = r;
  for (int k = 0; k < 3; k++) o->V[k] = f * l->color[k] / r2;
  o->fx = GI_FX_LOCAL;
  o->mpl = 0;
  return 1;
}

/* A light's intensity for the bounds: the sum of its colour, the measure
 * injection's roulette uses. */
static float light_power(const gi_light *l) { return l->color[0] + l->color[1] + l->color[2]; }

typedef struct {
  uint32_t light; /* index in s->lights */
  float key;      /* its position along the split axis */
  float pos[3];   /* local position */
} tree_item;

static int by_key(const void *a, const void *b) {
  float x = ((const tree_item *)a)->key, y = ((const tree_item *)b)->key;
  if (x != y) return x < y ? -1 : 1;
  /* Equal keys keep the lights' order: the build does not depend on qsort's. */
  uint32_t i = ((const tree_item *)a)->light, j = ((const tree_item *)b)->light;
  return i < j ? -1 : i > j;
}

typedef struct {
  const gi_scene *s;
  gi_local_node *nodes;
  uint32_t next;
} build_ctx;

/* Node `at` over items [0, n); its children go at bc->next onwards. */
static void build_node(build_ctx *bc, uint32_t at, tree_item *it, uint32_t n) {
  gi_local_node *nd = &bc->nodes[at];
  for (int k = 0; k < 3; k++) nd->lo[k] = FLT_MAX, nd->hi[k] = -FLT_MAX;
  double power = 0;
  for (uint32_t i = 0; i < n; i++) {
    for (int k = 0; k < 3; k++) nd->lo[k] = fminf(nd->lo[k], it[i].pos[k]), nd->hi[k] = fmaxf(nd->hi[k], it[i].pos[k]);
    power += light_power(&bc->s->lights[it[i].light]);
  }
  nd->power = (float)power;
  float h2 = 0;
  for (int k = 0; k < 3; k++) {
    nd->cen[k] = 0.5f * (nd->lo[k] + nd->hi[k]);
    float h = 0.5f * (nd->hi[k] - nd->lo[k]);
    h2 += h * h;
  }
  nd->h2 = h2;
  if (n == 1) {
    nd->light = it[0].light;
    nd->child = UINT32_MAX;
    return;
  }
  int axis = 0;
  for (int k = 1; k < 3; k++)
    if (nd->hi[k] - nd->lo[k] > nd->hi[axis] - nd->lo[axis]) axis = k;
  for (uint32_t i = 0; i < n; i++) it[i].key = it[i].pos[axis];
  qsort(it, n, sizeof *it, by_key);
  nd->light = UINT32_MAX;
  nd->child = bc->next;
  bc->next += 2;
  uint32_t half = n / 2;
  build_node(bc, nd->child, it, half);
  build_node(bc, nd->child + 1, it + half, n - half);
}

gi_result gi__local_tree_build(gi_scene *s, gi_error_info *err) {
  s->local_tree = NULL;
  s->num_local_nodes = 0;
  uint32_t n = 0;
  for (uint32_t i = 0; i < s->num_lights; i++)
    if (s->lights[i].type == GI_LIGHT_POINT || s->lights[i].type == GI_LIGHT_SPOT) n++;
  s->num_local = n;
  if (n < GI_LOCAL_TREE_MIN) return GI_OK;
  tree_item *it = gi__malloc((size_t)n * sizeof *it);
  gi_local_node *nodes = gi__calloc(2 * (size_t)n, sizeof *nodes);
  s->other_lights = gi__malloc((size_t)(s->num_lights - n + 1) * sizeof *s->other_lights);
  if (!it || !nodes || !s->other_lights) {
    gi__free(it);
    gi__free(nodes);
    return gi__fail(err, GI_ERR_NOMEM, "out of memory for the tree of %u point and spot lights", n);
  }
  for (uint32_t i = 0; i < s->num_lights; i++)
    if (s->lights[i].type != GI_LIGHT_POINT && s->lights[i].type != GI_LIGHT_SPOT) s->other_lights[s->num_other++] = i;
  /* Lights that send nothing take no place in the cut: their samples were zero. */
  uint32_t m = 0;
  for (uint32_t i = 0; i < s->num_lights; i++) {
    const gi_light *l = &s->lights[i];
    if ((l->type != GI_LIGHT_POINT && l->type != GI_LIGHT_SPOT) || !(light_power(l) > 0)) continue;
    it[m].light = i;
    for (int k = 0; k < 3; k++) it[m].pos[k] = (float)(l->position[k] - s->origin[k]);
    m++;
  }
  if (m == 0) {
    /* Every local light is dark: an empty tree, so no point samples them. */
    gi__free(it);
    s->local_tree = nodes;
    return GI_OK;
  }
  build_ctx bc = {.s = s, .nodes = nodes, .next = 1};
  build_node(&bc, 0, it, m);
  gi__free(it);
  s->local_tree = nodes;
  s->num_local_nodes = bc.next;
  return GI_OK;
}

/* Squared distance from p to node nd's box (0 inside it). */
static float box_d2(const gi_local_node *nd, const float p[3]) {
  float d2 = 0;
  for (int k = 0; k < 3; k++) {
    float d = gi__maxf(gi__maxf(nd->lo[k] - p[k], p[k] - nd->hi[k]), 0.f);
    d2 += d * d;
  }
  return d2;
}

/* What node nd may bring to p at most (infinite from inside its box). */
static float node_bound(const gi_local_node *nd, const float p[3]) {
  float d2 = box_d2(nd, p);
  return d2 > 0 ? nd->power / d2 : INFINITY;
}

/* A guess of what node nd brings to p, the picking weight: intensity over
 * the squared distance to its centre, no nearer than its half-diagonal. */
static float node_weight(const gi_local_node *nd, const float p[3]) {
  float d2 = 0;
  for (int k = 0; k < 3; k++) {
    float d = p[k] - nd->cen[k];
    d2 += d * d;
  }
  d2 = gi__maxf(gi__maxf(d2, nd->h2), 1e-12f);
  return nd->power / d2;
}

typedef struct {
  uint32_t node;
  float bound, est;
} cut_entry;

/* The max-heap of the cut's inner nodes, by bound. */
static void heap_push(cut_entry *h, int *n, cut_entry e) {
  int i = (*n)++;
  while (i > 0 && h[(i - 1) / 2].bound < e.bound) {
    h[i] = h[(i - 1) / 2];
    i = (i - 1) / 2;
  }
  h[i] = e;
}

static cut_entry heap_pop(cut_entry *h, int *n) {
  cut_entry top = h[0], last = h[--(*n)];
  int i = 0;
  for (;;) {
    int c = 2 * i + 1;
    if (c >= *n) break;
    if (c + 1 < *n && h[c + 1].bound > h[c].bound) c++;
    if (!(h[c].bound > last.bound)) break;
    h[i] = h[c];
    i = c;
  }
  h[i] = last;
  return top;
}

/* One light of inner node `node`, picked from p: its light index, and the
 * probability of the pick in *prob (in double: a float could round a rare
 * pick's to 0 and drop its light from the sum). */
static uint32_t pick_light(const gi_scene *s, uint32_t node, const float p[3], double u, double *prob) {
  const gi_local_node *t = s->local_tree;
  double pr = 1.0;
  while (t[node].light == UINT32_MAX) {
    uint32_t c = t[node].child;
    double w0 = node_weight(&t[c], p), w1 = node_weight(&t[c + 1], p);
    double p0 = w0 + w1 > 0 ? w0 / (w0 + w1) : 0.5;
    if (u < p0) {
      u = u / p0;
      pr *= p0;
      node = c;
    } else {
      u = (u - p0) / (1.0 - p0);
      pr *= 1.0 - p0;
      node = c + 1;
    }
    if (!(u < 1.0)) u = nextafter(1.0, 0.0);
  }
  *prob = pr;
  return t[node].light;
}

int gi__local_cut_samples(const gi_scene *s, const float p[3], int cut, uint64_t *rng, gi_lsample *out, int max) {
  if (!s->num_local_nodes || max <= 0 || cut <= 0) return 0;
  int limit = max < cut ? max : cut;
  if (limit > GI_LOCAL_CUT_MAX) limit = GI_LOCAL_CUT_MAX;
  const gi_local_node *t = s->local_tree;
  cut_entry heap[GI_LOCAL_CUT_MAX + 1];
  uint32_t leaves[GI_LOCAL_CUT_MAX + 1];
  int nh = 0, nl = 0;
  double total = 0;
  cut_entry root = {0, node_bound(&t[0], p), node_weight(&t[0], p)};
  if (t[0].light != UINT32_MAX) leaves[nl++] = 0;
  else heap_push(heap, &nh, root), total = root.est;
  /* Split the node that may bring the most while it may bring more than
   * its share of the cut's total. A leaf's guess is its light's own
   * unshadowed intensity over distance squared. */
  while (nh > 0 && nh + nl + 1 <= limit) {
    if (heap[0].bound <= GI_LOCAL_CUT_SHARE * total) break;
    cut_entry e = heap_pop(heap, &nh);
    total -= e.est;
    for (uint32_t c = t[e.node].child; c < t[e.node].child + 2; c++) {
      cut_entry ce = {c, node_bound(&t[c], p), node_weight(&t[c], p)};
      total += ce.est;
      if (t[c].light != UINT32_MAX) leaves[nl++] = c;
      else heap_push(heap, &nh, ce);
    }
  }
  int n = 0;
  for (int i = 0; i < nl; i++) n += gi__local_sample(s, &s->lights[t[leaves[i]].light], p, &out[n]);
  /* The nodes left whole: one light each, in heap order (deterministic). */
  for (int i = 0; i < nh; i++) {
    double prob, u = (double)gi__u01(rng);
    uint32_t li = pick_light(s, heap[i].node, p, u, &prob);
    if (!(prob > 0) || !gi__local_sample(s, &s->lights[li], p, &out[n])) continue;
    /* Finite whatever the pick: a lamp far nearer than its group's centre
     * (a full cut around the point) could exceed float's range. */
    for (int k = 0; k < 3; k++) out[n].V[k] = (float)fmin((double)out[n].V[k] / prob, FLT_MAX);
    n++;
  }
  return n;
}
