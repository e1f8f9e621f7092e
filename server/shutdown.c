/* shutdown.c: SIGINT/SIGTERM, bounded.
 *
 * main.c waits for the first signal, calls gs_shutdown_begin, then stops
 * the front (no new connections), the worker pool and the job runners in
 * that order and exits 0. What could make that wait long is cut here:
 * running jobs are cancelled (they stop inside their bake or gather), a
 * second signal exits at once, and when shutdown_grace_s passes with work
 * still running the process exits anyway. Both forced exits remove the
 * private folder and use status GS_EXIT_FORCED, so a supervisor can tell
 * them from a clean stop. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>
#include "server.h"

typedef struct {
  sigset_t sigs;
  double grace_s;
  gs_jobs *jobs;
} watchdog_args;

static void *watchdog(void *p) {
  watchdog_args *w = p;
  double end = gs_now_ms() + w->grace_s * 1e3;
  for (;;) {
    double left = (end - gs_now_ms()) * 1e-3;
    if (left <= 0) break;
    struct timespec ts = {(time_t)floor(left), (long)((left - floor(left)) * 1e9)};
    int sig = sigtimedwait(&w->sigs, NULL, &ts);
    if (sig > 0) {
      fprintf(stderr, "gi-server: second %s: exiting now\n", gs_signal_name(sig));
      gs_jobs_abandon(w->jobs);
      _exit(GS_EXIT_FORCED);
    }
    if (errno != EINTR && errno != EAGAIN) break;
  }
  fprintf(stderr, "gi-server: still busy after the shutdown grace of %g s ([server] shutdown_grace_s): exiting now\n",
          w->grace_s);
  gs_jobs_abandon(w->jobs);
  _exit(GS_EXIT_FORCED);
  return NULL;
}

void gs_shutdown_begin(gs_service *svc, const sigset_t *sigs) {
  static watchdog_args w;
  w.sigs = *sigs;
  w.grace_s = svc->cfg->shutdown_grace_s;
  w.jobs = svc->jobs;
  gs_jobs_cancel_all(svc->jobs);
  pthread_t t;
  /* The signals stay blocked in every thread; this one takes the second. */
  if (pthread_create(&t, NULL, watchdog, &w) == 0) pthread_detach(t);
  else fprintf(stderr, "gi-server: cannot start the shutdown watchdog: the grace is not enforced\n");
}
