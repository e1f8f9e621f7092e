/* gi_error.h: result codes shared by every core function.
 *
 * Every fallible function returns a gi_result. Codes are pinned numbers from
 * one X-macro list; never renumber them (the HTTP layer maps them to statuses).
 * Detailed messages go into a caller-owned gi_error_info, so they are
 * per-call and thread-safe (no global "last error"). */
#ifndef GI_ERROR_H
#define GI_ERROR_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define GI_RESULT_LIST(X)                                              \
  X(GI_OK, 0, "success")                                               \
  X(GI_ERR_INVALID_ARG, 1, "invalid argument")                         \
  X(GI_ERR_NOMEM, 2, "out of memory")                                  \
  X(GI_ERR_IO, 3, "input/output error")                                \
  X(GI_ERR_FORMAT, 4, "malformed or unsupported file")                 \
  X(GI_ERR_NOT_FOUND, 5, "not found")                                  \
  X(GI_ERR_NONFINITE, 6, "non-finite value")                           \
  X(GI_ERR_EMPTY, 7, "nothing to work on")                             \
  X(GI_ERR_LIMIT, 8, "limit exceeded")                                 \
  X(GI_ERR_BACKEND, 9, "a dependency (Embree, OpenEXR, OpenVDB) failed") \
  X(GI_ERR_INTERNAL, 10, "internal error")                            \
  X(GI_ERR_CANCELLED, 11, "cancelled or past its deadline")

typedef int32_t gi_result;
enum {
#define GI__ENUM(name, value, text) name = value,
  GI_RESULT_LIST(GI__ENUM)
#undef GI__ENUM
};

/* Caller-allocated detail for one failing call: the code and a message that
 * names the file, field or line and what was expected. Zero-initialise it. */
typedef struct gi_error_info {
  gi_result code;
  char msg[512];
} gi_error_info;

/* Static text for a code ("invalid argument"); never NULL. Thread-safe. */
const char *gi_strerror(gi_result r);
/* The code's name ("GI_ERR_INVALID_ARG"); never NULL. Thread-safe. */
const char *gi_err_name(gi_result r);

#ifdef __cplusplus
}
#endif
#endif
