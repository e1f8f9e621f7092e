/* gi_points.h: the probe-point file both command-line tools read
 * (gi-bake --probes, gi-client --points): one "x y z" per line (blanks,
 * one comma, or both between numbers: "1, 0.5, 2"), '#' starts a comment,
 * blank lines are skipped, and the first line may name the three columns
 * ("x,y,z", or quoted: "\"x\",\"y\",\"z\"").
 * Thread-safe; the caller owns *pts (free()). */
#ifndef GI_POINTS_H
#define GI_POINTS_H

#include <stddef.h>
#include "gi_error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Reads up to max points into *pts (3 doubles each) and *n. Errors:
 * GI_ERR_IO (cannot open or read), GI_ERR_FORMAT (a line that is not three
 * finite numbers, named "PATH:LINE"), GI_ERR_LIMIT (more than max),
 * GI_ERR_NOMEM. On error *pts is NULL and *n is 0. */
gi_result gi_points_read(const char *path, size_t max, double **pts, size_t *n, gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
