/* clock.c: the monotonic clock every stage times itself with, and the
 * cancel token's deadlines are read against. */
#include <time.h>
#include "base/internal.h"

double gi__now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}
