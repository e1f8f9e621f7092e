/* half.h: IEEE binary16 conversions for the cascade's texels (not installed).
 *
 * Portable bit arithmetic (after F. Giesen's public-domain conversions):
 * the writers use it everywhere, and the march's baseline path reads with
 * it; the x86-64-v3 path reads with the F16C instruction instead, which
 * gives the same floats. Rounding is to nearest even; values beyond
 * 65504 become infinity, which the writers never produce (cascade/texel.c
 * scales radiance first). */
#ifndef GI_HALF_H
#define GI_HALF_H

#include <stdint.h>

static inline float gi__h2f(uint16_t h) {
  union { uint32_t u; float f; } v, magic = {.u = (254u - 15u) << 23};
  uint32_t em = (uint32_t)h & 0x7fffu;
  v.u = em << 13;
  v.f *= magic.f; /* rebias the exponent; also normalises subnormals */
  if (em >= 0x7c00u) v.u |= 0x7f800000u; /* infinity and NaN stay so */
  v.u |= (uint32_t)(h & 0x8000u) << 16;
  return v.f;
}

static inline uint16_t gi__f2h(float f) {
  union { uint32_t u; float f; } v = {.f = f}, denorm = {.u = 0x3f000000u};
  uint32_t sign = v.u & 0x80000000u;
  uint16_t o;
  v.u ^= sign;
  if (v.u >= 0x47800000u) { /* 65536 and up: infinity, or NaN */
    o = v.u > 0x7f800000u ? 0x7e00u : 0x7c00u;
  } else if (v.u < 0x38800000u) { /* under 2^-14: a subnormal half or zero */
    v.f += denorm.f;           /* the addition rounds to nearest even */
    o = (uint16_t)(v.u - denorm.u);
  } else {
    uint32_t odd = (v.u >> 13) & 1u;
    v.u += 0xc8000fffu + odd;  /* rebias by (15 - 127) << 23, round half to even */
    o = (uint16_t)(v.u >> 13);
  }
  return (uint16_t)(o | (sign >> 16));
}

#endif
