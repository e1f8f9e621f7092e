/* error.c: result-code names and texts, and the detail-message helper. */
#include <stdio.h>
#include "base/internal.h"

const char *gi_strerror(gi_result r) {
  switch (r) {
#define GI__TEXT(name, value, text) case name: return text;
    GI_RESULT_LIST(GI__TEXT)
#undef GI__TEXT
  }
  return "unknown error";
}

const char *gi_err_name(gi_result r) {
  switch (r) {
#define GI__NAME(name, value, text) case name: return #name;
    GI_RESULT_LIST(GI__NAME)
#undef GI__NAME
  }
  return "GI_ERR_UNKNOWN";
}

gi_result gi__fail(gi_error_info *err, gi_result code, const char *fmt, ...) {
  if (err) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    va_end(ap);
    err->code = code;
  }
  return code;
}
