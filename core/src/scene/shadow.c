/* shadow.c: shadow-ray batches, with the one rule every stage uses for
 * where a shadow ray starts and where it stops (see lights.h). */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "scene/lights.h"

int gi__scratch_alloc(gi_ray_scratch *sc, int cap) {
  size_t n = (size_t)(cap > 0 ? cap : 1);
  sc->cap = cap;
  sc->ls = gi__malloc(n * sizeof *sc->ls);
  sc->org = gi__malloc(n * 3 * sizeof(float));
  sc->dir = gi__malloc(n * 3 * sizeof(float));
  sc->tn = gi__malloc(n * sizeof(float));
  sc->tf = gi__malloc(n * sizeof(float));
  sc->vis = gi__malloc(n);
  if (sc->ls && sc->org && sc->dir && sc->tn && sc->tf && sc->vis) return 0;
  gi__scratch_free(sc);
  return -1;
}

void gi__scratch_free(gi_ray_scratch *sc) {
  gi__free(sc->ls); gi__free(sc->org); gi__free(sc->dir); gi__free(sc->tn); gi__free(sc->tf); gi__free(sc->vis);
  sc->ls = NULL, sc->org = sc->dir = sc->tn = sc->tf = NULL, sc->vis = NULL;
}
