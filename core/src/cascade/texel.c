/* texel.c: the cascade's half-float texels in and out of float.
 *
 * Radiance lanes are stored divided by rad_scale, the brightest radiance
 * over GI_RAD_BRIGHTEST_STORED: filtering composites up to two children
 * per column and the march only sums texels, so no stored value comes
 * near half's largest, 65504. The scale is proportional to the light (not
 * rounded to a power of two), so a scene lit a million times brighter
 * stores the same halves: lighting stays linear in the lights. */
#include <float.h>
#include <math.h>
#include "cascade/cascade_internal.h"

/* The brightest texel is stored at most this large (65504 / 4096: room
 * for filtering's sums sixteen times over). Dim light keeps full half
 * precision down to 2^-14 of it, 6e-5 / 4096 = 1.5e-8 of the brightest. */
#define GI_RAD_BRIGHTEST_STORED 4096.0f

void gi__vrad_unpack(const struct gi_cascade *c, const gi_vrad *r, gi_vrad_f *out) {
  float *o = &out->p[0][0];
  for (int i = 0; i < GI_VRAD_ALPHA; i++) o[i] = gi__h2f(r->h[i]) * c->rad_scale;
  for (int a = 0; a < 3; a++) {
    out->alpha[a] = gi__h2f(r->h[GI_VRAD_ALPHA + a]);
    out->tau[a] = gi__h2f(r->h[GI_VRAD_TAU + a]);
  }
}

void gi__vrad_pack(const struct gi_cascade *c, const gi_vrad_f *in, gi_vrad *r) {
  const float *p = &in->p[0][0];
  float inv = 1.0f / c->rad_scale;
  for (int i = 0; i < GI_VRAD_ALPHA; i++) r->h[i] = gi__f2h(p[i] * inv);
  for (int a = 0; a < 3; a++) {
    r->h[GI_VRAD_ALPHA + a] = gi__f2h(in->alpha[a]);
    r->h[GI_VRAD_TAU + a] = gi__f2h(in->tau[a]);
  }
}

/* At least FLT_MIN: under 1.5e-35 of brightest the scale went subnormal,
 * its inverse Inf, and an unlit texel's 0 x Inf NaN (a scene lit only by
 * a 1e-35 sun failed). Light that dim keeps half's precision relative to
 * FLT_MIN instead, which loses nothing a float could show. */
void gi__vrad_rescale(struct gi_cascade *c, float brightest) {
  c->rad_scale = brightest > 0 && isfinite(brightest) ? fmaxf(brightest / GI_RAD_BRIGHTEST_STORED, FLT_MIN) : 1.0f;
}
