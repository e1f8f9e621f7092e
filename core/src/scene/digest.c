/* digest.c: gi_scene_digest, a hash of what a loaded scene holds.
 *
 * It hashes the scene as built, not the files it came from: a glTF's
 * external .bin buffers and a material's texture (averaged into each
 * triangle's albedo) reach the answers only through these arrays, so an
 * edit of any file the loader read changes the digest, and an edit that
 * changes nothing loaded (a comment) does not. A word at a time with a
 * murmur-style mix: byte-wise FNV took about 4 cycles a byte, too slow
 * for the tens of megabytes of a million-triangle scene on every
 * --resume. Raw float bytes in the host's (little-endian) order: the
 * digest is for comparing bakes of one build on x86-64. */
#include <string.h>
#include "scene/scene_internal.h"

#define DIGEST_VERSION "gi-scene-digest 1"

static uint64_t rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

static uint64_t mix(uint64_t h, uint64_t k) {
  k *= 0x87c37b91114253d5ull;
  k = rotl(k, 31);
  k *= 0x4cf5ad432745937full;
  h ^= k;
  return rotl(h, 27) * 5 + 0x52dce729;
}

/* n bytes, their count too: arrays of different lengths never run together. */
static uint64_t bytes(uint64_t h, const void *p, size_t n) {
  const unsigned char *b = p;
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    uint64_t k;
    memcpy(&k, b + i, 8);
    h = mix(h, k);
  }
  uint64_t k = 0;
  if (n > i) memcpy(&k, b + i, n - i);
  return mix(mix(h, k), (uint64_t)n);
}

static uint64_t u64(uint64_t h, uint64_t v) { return mix(h, v); }

/* Field by field: the structs' padding and a name's bytes past its end are
 * not content. A material's name is left out (no answer reads it). */
static uint64_t materials(uint64_t h, const gi_scene *s) {
  h = u64(h, s->num_materials);
  for (uint32_t i = 0; i < s->num_materials; i++) {
    const gi_material *m = &s->materials[i];
    float f[12] = {m->albedo[0],       m->albedo[1],       m->albedo[2],      m->emission[0],
                   m->emission[1],     m->emission[2],     m->roughness,      m->specular,
                   m->specular_rgb[0], m->specular_rgb[1], m->specular_rgb[2], (float)m->two_sided};
    h = bytes(h, f, sizeof f);
  }
  return h;
}

static uint64_t lights(uint64_t h, const gi_scene *s) {
  h = u64(h, s->num_lights);
  for (uint32_t i = 0; i < s->num_lights; i++) {
    const gi_light *l = &s->lights[i];
    double d[12] = {(double)l->type,     l->color[0],         l->color[1],         l->color[2],
                    l->position[0],      l->position[1],      l->position[2],      l->direction[0],
                    l->direction[1],     l->direction[2],     l->cos_inner,        l->cos_outer};
    h = bytes(h, d, sizeof d);
  }
  return h;
}

uint64_t gi_scene_digest(const gi_scene *s) {
  uint64_t h = bytes(0x9e3779b97f4a7c15ull, DIGEST_VERSION, sizeof DIGEST_VERSION);
  if (!s) return h;
  h = u64(h, (uint64_t)s->up);
  double box[9] = {s->origin[0], s->origin[1], s->origin[2], s->bulk_lo[0], s->bulk_lo[1], s->bulk_lo[2],
                   s->bulk_hi[0], s->bulk_hi[1], s->bulk_hi[2]};
  h = bytes(h, box, sizeof box);
  h = u64(h, s->stats.far_triangles);
  h = bytes(h, s->vertices, 3 * (size_t)s->num_vertices * sizeof *s->vertices);
  h = u64(h, s->uv2 != NULL);
  if (s->uv2) h = bytes(h, s->uv2, 2 * (size_t)s->num_vertices * sizeof *s->uv2);
  h = bytes(h, s->indices, 3 * (size_t)s->num_triangles * sizeof *s->indices);
  h = bytes(h, s->tri_material, (size_t)s->num_triangles * sizeof *s->tri_material);
  h = u64(h, s->tri_albedo != NULL);
  if (s->tri_albedo) h = bytes(h, s->tri_albedo, 3 * (size_t)s->num_triangles * sizeof *s->tri_albedo);
  h = lights(materials(h, s), s);
  /* murmur3's finaliser: every input bit reaches every output bit. */
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  return h ^ (h >> 33);
}
