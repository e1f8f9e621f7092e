/* gi_cancel.h: stop a bake, a move or a gather early.
 *
 * A gi_cancel is a token the caller creates and hands to
 * gi_cascade_bake_ex, gi_cascade_bake_for, gi_cascade_move_ex,
 * gi_cascade_gather_ex, gi_cascade_panorama_ex or gi_lightmap_bake. The
 * call checks it between chunks of work (voxel slabs, voxel batches, probe
 * batches, panorama rows, texels) and returns
 * GI_ERR_CANCELLED soon after it is set or its deadline passes (a chunk
 * takes milliseconds). A cancelled call leaks nothing. What it leaves: a
 * bake no cascade (*out NULL); a gather, panorama or lightmap bake its
 * output partly written (not to be read); a move a partial cascade, which
 * every later read refuses and the next move bakes afresh (gi_move.h). Renders,
 * the path tracer and the writers take no token.
 *
 * Ownership: the caller owns the token (gi_cancel_new / gi_cancel_free)
 * and keeps it alive longer than every call it was given to. One token may
 * serve any number of calls at once.
 * Thread-safety: gi_cancel_set and gi_cancel_set_deadline may be called
 * from any thread while calls read the token from theirs; a set token
 * stays set. Times are monotonic milliseconds (gi_now_ms). */
#ifndef GI_CANCEL_H
#define GI_CANCEL_H

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_cancel gi_cancel;

/* Why a token fired. */
typedef enum gi_cancel_reason {
  GI_CANCEL_NONE = 0,     /* not fired */
  GI_CANCEL_REQUESTED = 1, /* gi_cancel_set was called */
  GI_CANCEL_DEADLINE = 2  /* the deadline passed */
} gi_cancel_reason;

/* A fresh token: not set, no deadline. NULL when out of memory. */
gi_cancel *gi_cancel_new(void);
void gi_cancel_free(gi_cancel *c); /* accepts NULL */
/* Asks every call holding the token to stop. */
void gi_cancel_set(gi_cancel *c);
/* Calls stop once gi_now_ms() passes deadline_ms; 0 removes the deadline.
 * A negative or NaN deadline has passed; +Inf is never reached. */
void gi_cancel_set_deadline(gi_cancel *c, double deadline_ms);
/* Whether the token fired, and why (a request wins over a deadline).
 * NULL never fires. */
gi_cancel_reason gi_cancel_check(const gi_cancel *c);
/* The monotonic clock the deadlines use, in milliseconds. */
double gi_now_ms(void);

#ifdef __cplusplus
}
#endif
#endif
