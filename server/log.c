/* log.c: what a client sent, made safe to write into the log.
 *
 * Paths and methods come decoded from the client: a "%0d%0a" in a path is a
 * real CR LF, which written raw would forge a log line. Every byte outside
 * printable ASCII, and the backslash itself, is written as \xNN, so one
 * request is always one line and the original bytes can be read back. */
#include <stdio.h>
#include "server.h"

void gs_log_escape(const char *in, char *out, size_t size) {
  static const char hex[] = "0123456789abcdef";
  enum { ESCAPED_LEN = 4 }; /* \xNN */
  size_t o = 0;
  if (!size) return;
  for (const unsigned char *p = (const unsigned char *)in; *p; p++) {
    int plain = *p >= 0x20 && *p < 0x7f && *p != '\\';
    size_t need = plain ? 1 : ESCAPED_LEN;
    if (o + need >= size) break;
    if (plain) {
      out[o++] = (char)*p;
    } else {
      out[o++] = '\\';
      out[o++] = 'x';
      out[o++] = hex[*p >> 4];
      out[o++] = hex[*p & 15];
    }
  }
  out[o] = 0;
}
