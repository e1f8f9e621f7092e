/* gi_bake.h: the bake in one include: quality and effects, the cascade,
 * probes and panoramas, and the output writers. Kept for callers written
 * against v0.1; new code may include the subject headers it needs, each
 * of which says who owns what and what is thread-safe. */
#ifndef GI_BAKE_H
#define GI_BAKE_H

#include "gi_cascade.h"
#include "gi_output.h"
#include "gi_probe.h"
#include "gi_quality.h"

#endif
