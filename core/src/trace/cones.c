/* cones.c: diffuse cone sets and the tangent frame they are turned into.
 *
 * A hemisphere is split into rings of regions of equal solid angle
 * 2 pi / N; each cone points at its ring's cosine-weighted mean elevation
 * and has the region's solid angle, and its weight is the exact integral
 * of cos(theta) over the region, so the weights sum to pi and a uniform
 * radiance L gathers exactly E = pi L. */
#include <string.h>
#include "base/internal.h"
#include "trace/trace.h"

static const int ring_layout[][6] = {
    /* N, rings... (0 terminated) */
    {4, 1, 3, 0, 0, 0}, {6, 1, 5, 0, 0, 0}, {8, 1, 7, 0, 0, 0}, {16, 1, 6, 9, 0, 0}, {32, 1, 6, 11, 14, 0},
    /* Regions about 17 degrees on a side: the probes' final gather. */
    {64, 1, 6, 12, 18, 27},
};

void gi__cone_set(int count, float aperture_deg, float dirs[][3], float weights[], float *tan_half) {
  const int *layout = NULL;
  for (size_t i = 0; i < sizeof ring_layout / sizeof ring_layout[0]; i++)
    if (ring_layout[i][0] == count) layout = &ring_layout[i][1];
  if (!layout) layout = ring_layout[3] + 1, count = 16;
  const double pi = 3.14159265358979323846;
  int idx = 0, cum = 0;
  double cos_a = 1.0;
  for (int r = 0; r < 5 && layout[r]; r++) {
    int nr = layout[r];
    cum += nr;
    double cos_b = 1.0 - (double)cum / count;
    if (cos_b < 0) cos_b = 0;
    /* A ring's cones sit at its cosine-weighted mean elevation, so the set
     * reproduces the lobe's first moment; the cap's cone stays on the axis. */
    double cos_c = r == 0 ? 1.0
                          : (2.0 / 3.0) * (cos_a * cos_a * cos_a - cos_b * cos_b * cos_b) /
                                (cos_a * cos_a - cos_b * cos_b);
    double sin_c = sqrt(1.0 - cos_c * cos_c);
    double w = pi * (cos_a * cos_a - cos_b * cos_b) / nr;
    for (int i = 0; i < nr; i++) {
      double phi = 2 * pi * (i + 0.5 * (r & 1)) / nr;
      dirs[idx][0] = (float)(sin_c * cos(phi));
      dirs[idx][1] = (float)(sin_c * sin(phi));
      dirs[idx][2] = (float)cos_c;
      weights[idx] = (float)w;
      idx++;
    }
    cos_a = cos_b;
  }
  double half;
  if (aperture_deg > 0) {
    half = 0.5 * aperture_deg * pi / 180.0;
  } else {
    /* A cone whose solid angle equals its region's: 2 pi (1 - cos h) = 2 pi / N. */
    half = acos(1.0 - 1.0 / count);
  }
  *tan_half = (float)tan(half);
}

#define PROBE_DENSE_FROM 16 /* bake cones from which probes take the dense set */

int gi__probe_cone_count(int bake_count) {
  return bake_count < PROBE_DENSE_FROM ? bake_count : GI_MAX_CONES;
}

/* A set of `count` cones derived from the bake's: a chosen aperture
 * narrows or widens them by the same factor against their matched width
 * as it does the bake's. */
static void derived_set(int bake_count, int count, float aperture_deg, float dirs[][3], float weights[],
                        float *tan_half) {
  float user = 0;
  if (aperture_deg > 0) {
    double matched_bake = acos(1.0 - 1.0 / bake_count), matched = acos(1.0 - 1.0 / count);
    user = (float)(aperture_deg * matched / matched_bake);
  }
  gi__cone_set(count, user, dirs, weights, tan_half);
}

void gi__probe_cone_set(int bake_count, float aperture_deg, float dirs[][3], float weights[], float *tan_half) {
  derived_set(bake_count, gi__probe_cone_count(bake_count), aperture_deg, dirs, weights, tan_half);
}

#define WIDE_CONES 8 /* the later bounces' set (1 + 7, 58 degrees matched) */

int gi__wide_cone_count(int bake_count) { return bake_count < WIDE_CONES ? bake_count : WIDE_CONES; }

void gi__wide_cone_set(int bake_count, float aperture_deg, float dirs[][3], float weights[], float *tan_half) {
  derived_set(bake_count, gi__wide_cone_count(bake_count), aperture_deg, dirs, weights, tan_half);
}
