/* main.c: gi-server's command line, start-up order and shutdown.
 *
 * Start-up fails early and loudly: the config is validated and every
 * scene is loaded before the port opens, so "listening" means "ready".
 * SIGINT/SIGTERM/SIGHUP stop accepting, let running requests finish, and exit 0. */
#define _POSIX_C_SOURCE 200809L
#include <arpa/inet.h>
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "gi/gi_cpu.h"
#include "server.h"
#include "toolargs.h"

static const char help_text[] =
    "Usage: gi-server [--config FILE] [--port N] [--bind ADDR] [--port-file F]\n"
    "                 [--check-config] [--version] [--help]\n"
    "Serves global illumination over HTTP: probes and panoramas as EXR, cascade\n"
    "snapshots as VDB, probe lists as jobs, Prometheus metrics. See proto/openapi.yaml.\n"
    "\n"
    "  --config FILE   INI config (default configs/gi-server.ini); scene paths in it\n"
    "                  are relative to the file\n"
    "  --port N        override [server] port (0 = an ephemeral port)\n"
    "  --bind ADDR     override [server] bind (an IPv4 address)\n"
    "  --port-file F   write the bound port number to F once listening\n"
    "  --check-config  validate the config and load the scenes, then exit\n"
    "  -V, --version   the version and the march's CPU path;  -h, --help  this text\n"
    "\n"
    "Environment: GI_SERVER_TOKEN overrides [server] token_file (bearer token);\n"
    "GI_CPU_PATH=baseline|x86-64-v3|auto picks the cone march's build (another\n"
    "value: exit 2).\n"
    "Exit status: 0 clean shutdown or valid config, 1 start-up failed, 2 bad arguments,\n"
    "3 shutdown forced (a second signal, or work still running after shutdown_grace_s).\n";

static int write_port_file(const char *path, int port) {
  char tmp[1100];
  snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
  FILE *f = fopen(tmp, "w");
  if (!f) return -1;
  fprintf(f, "%d\n", port);
  if (fclose(f) != 0 || rename(tmp, path) != 0) {
    unlink(tmp);
    return -1;
  }
  return 0;
}

/* The tools' one rule for integers (tools/common): digits only, in range. */
static int parse_port(const char *s, int *out) {
  long long v;
  if (ta_parse_ll(s, 0, 65535, &v) != TA_OK) return -1;
  *out = (int)v;
  return 0;
}

/* What the command line asked for. */
typedef struct server_args {
  const char *config, *port_file, *bind;
  int port;  /* -1: the config's */
  int check; /* --check-config */
} server_args;

/* Parses argv into a. Returns -1 to go on, else the exit status (0 after
 * --help or --version, 2 for bad arguments). */
static int parse_args(int argc, char **argv, server_args *a) {
  static const struct option opts[] = {{"config", required_argument, NULL, 'c'},
                                       {"port", required_argument, NULL, 'p'},
                                       {"bind", required_argument, NULL, 'b'},
                                       {"port-file", required_argument, NULL, 'f'},
                                       {"check-config", no_argument, NULL, 'k'},
                                       {"version", no_argument, NULL, 'V'},
                                       {"help", no_argument, NULL, 'h'},
                                       {NULL, 0, NULL, 0}};
  *a = (server_args){.config = "configs/gi-server.ini", .port = -1};
  opterr = 0;
  int o, idx = -1;
  unsigned seen = 0; /* options with a value, by index in opts */
  while ((o = getopt_long(argc, argv, ":hV", opts, &idx)) != -1) {
    /* A second --config (or --port, ...) silently replaced the first. */
    if (idx >= 0 && opts[idx].has_arg && o != ':') {
      if (seen & (1u << idx)) {
        fprintf(stderr, "gi-server: --%s given twice (it takes one value)\n", opts[idx].name);
        return 2;
      }
      seen |= 1u << idx;
    }
    idx = -1;
    switch (o) {
    case 'c': a->config = optarg; break;
    case 'p':
      if (parse_port(optarg, &a->port)) {
        fprintf(stderr, "gi-server: --port: expected 0..65535, got '%s'\n", optarg);
        return 2;
      }
      break;
    case 'b': {
      /* Checked here: at listen time the error blamed the config's [server]
       * bind, with exit 1, after every scene had loaded. */
      struct in_addr ia;
      if (strlen(optarg) >= sizeof ((gs_config *)0)->bind || inet_pton(AF_INET, optarg, &ia) != 1) {
        fprintf(stderr, "gi-server: --bind: expected an IPv4 address, got '%s'\n", optarg);
        return 2;
      }
      a->bind = optarg;
      break;
    }
    case 'f': a->port_file = optarg; break;
    case 'k': a->check = 1; break;
    case 'V': printf("gi-server %s\ncpu path: %s\n", ta_version(), gi_cpu_path()); return 0;
    case 'h': fputs(help_text, stdout); return 0;
    case ':': fprintf(stderr, "gi-server: %s needs a value\n", argv[optind - 1]); return 2;
    default: fprintf(stderr, "gi-server: unknown option '%s' (see --help)\n", argv[optind - 1]); return 2;
    }
  }
  if (optind < argc) {
    fprintf(stderr, "gi-server: unexpected argument '%s' (see --help)\n", argv[optind]);
    return 2;
  }
  return -1;
}

/* Loads the config and applies what overrides it: --port, --bind,
 * GI_SERVER_TOKEN, TMPDIR. Returns 0, or 1 after printing why not. */
static int load_config(const server_args *a, gs_config *cfg) {
  char err[1200];
  gs_config_defaults(cfg);
  if (gs_config_load(a->config, cfg, err, sizeof err)) {
    fprintf(stderr, "gi-server: %s\n", err);
    return 1;
  }
  if (a->port >= 0) cfg->port = a->port;
  if (a->bind) snprintf(cfg->bind, sizeof cfg->bind, "%s", a->bind);
  const char *tok = getenv("GI_SERVER_TOKEN");
  if (tok && *tok) {
    const char *why = gs_token_bad(tok);
    if (why) {
      fprintf(stderr, "gi-server: GI_SERVER_TOKEN %s\n", why);
      return 1;
    }
    snprintf(cfg->token, sizeof cfg->token, "%s", tok);
  }
  if (!cfg->tmp_dir[0]) {
    const char *t = getenv("TMPDIR");
    snprintf(cfg->tmp_dir, sizeof cfg->tmp_dir, "%s", t && *t ? t : "/tmp");
  }
  struct stat st;
  if (stat(cfg->tmp_dir, &st) != 0 || !S_ISDIR(st.st_mode) || access(cfg->tmp_dir, W_OK) != 0) {
    fprintf(stderr, "gi-server: %s: [server] tmp_dir: '%s' is not a writable folder\n", cfg->path, cfg->tmp_dir);
    return 1;
  }
  if (cfg->num_scenes == 0) {
    fprintf(stderr, "gi-server: %s: no [scene ID] sections: nothing to serve\n", cfg->path);
    return 1;
  }
  return 0;
}

/* Signals go to one thread (sigwait in main); every other thread, started
 * after this, blocks them. */
static void block_signals(sigset_t *sigs) {
  sigemptyset(sigs);
  sigaddset(sigs, SIGINT);
  sigaddset(sigs, SIGTERM);
  /* A closed terminal: the same clean stop (it killed the server outright,
   * its private folder left for the next start). There is no reload. */
  sigaddset(sigs, SIGHUP);
  pthread_sigmask(SIG_BLOCK, sigs, NULL);
  signal(SIGPIPE, SIG_IGN);
}

/* Loads every scene of the config. Returns 0, or 1 after printing why not. */
static int load_catalog(const gs_config *cfg, gs_catalog *cat) {
  char err[1200];
  if (gs_catalog_load(cfg, cat, err, sizeof err)) {
    fprintf(stderr, "gi-server: %s\n", err);
    return 1;
  }
  if (cat->num == 0) {
    fprintf(stderr, "gi-server: %s: every scene was optional and absent: nothing to serve\n", cfg->path);
    return 1;
  }
  return 0;
}

/* Metrics, cache, worker pool and jobs. Returns 0, or 1 after printing why not. */
static int start_service(gs_service *svc, const gs_config *cfg, const gs_catalog *cat) {
  svc->cfg = cfg;
  svc->cat = cat;
  svc->start_ms = gs_now_ms();
  svc->metrics = gs_metrics_new();
  svc->cache = gs_cache_new(cfg->cache_bytes, svc->metrics);
  svc->pool = gs_pool_new(cfg->workers, cfg->queue);
  svc->jobs = svc->pool ? gs_jobs_new(svc) : NULL;
  svc->sessions = gs_sessions_new(svc);
  if (!svc->metrics || !svc->cache || !svc->pool || !svc->jobs || !svc->sessions) {
    fprintf(stderr, "gi-server: cannot start the workers (out of memory or threads)\n");
    return 1;
  }
  /* A budget too small for a scene's default bake refuses every default request (413): say so now. */
  for (size_t i = 0; i < cat->num && cfg->cache_bytes; i++) {
    size_t need = gs_bake_bytes(&cat->scenes[i].quality);
    if (need > cfg->cache_bytes)
      fprintf(stderr, "gi-server: warning: scene '%s': a default bake needs %zu MiB, more than cache_mb = %zu\n",
              cat->scenes[i].id, need >> 20, cfg->cache_bytes >> 20);
  }
  return 0;
}

/* The "listening" line and a curl command that works against this server
 * (-L: the viewpoint URL answers 307 to its cell, whose body is the EXR). */
static void announce(const gs_config *cfg, const gs_catalog *cat, int bound) {
  const gs_scene *first = &cat->scenes[0];
  printf("gi-server %s listening on http://%s:%d (%zu scene(s), %d workers, queue %d, cache %zu MiB%s)\n",
         GI_VERSION, cfg->bind, bound, cat->num, cfg->workers, cfg->queue, cfg->cache_bytes >> 20,
         cfg->token[0] ? ", bearer token required" : "");
  printf("try: curl -L -o %s-probe.exr 'http://%s:%d/v1/scenes/%s/lighting?at=%.6g,%.6g,%.6g'%s\n", first->id,
         cfg->bind, bound, first->id, first->default_at[0], first->default_at[1], first->default_at[2],
         cfg->token[0] ? " -H \"Authorization: Bearer $TOKEN\"" : "");
  fflush(stdout);
}

/* Stops accepting, lets running requests finish, frees everything. */
static void stop_service(gs_http *h, gs_service *svc, gs_catalog *cat, gs_config *cfg) {
  gs_http_stop(h);
  gs_pool_free(svc->pool);
  gs_jobs_free(svc->jobs);
  /* Sessions give their bytes back to the cache's budget: before the cache goes. */
  gs_sessions_free(svc->sessions);
  gs_cache_free(svc->cache);
  gs_metrics_free(svc->metrics);
  gs_catalog_free(cat);
  gs_config_free(cfg);
}

int main(int argc, char **argv) {
  server_args args;
  char why[256];
  /* Before anything: /v1/health would report a path the user did not ask for. */
  if (gi_cpu_path_check(why, sizeof why)) {
    fprintf(stderr, "gi-server: %s\n", why);
    return 2;
  }
  int rc = parse_args(argc, argv, &args);
  if (rc >= 0) return rc;
  static gs_config cfg;
  if (load_config(&args, &cfg)) return 1;
  sigset_t sigs;
  block_signals(&sigs);
  static gs_catalog cat;
  if (load_catalog(&cfg, &cat)) return 1;
  if (args.check) {
    printf("gi-server: %s is valid: %zu scene(s)\n", cfg.path, cat.num);
    gs_catalog_free(&cat);
    gs_config_free(&cfg);
    return 0;
  }
  static gs_service svc;
  if (start_service(&svc, &cfg, &cat)) return 1;
  char err[1200];
  gs_http *h = gs_http_start(&svc, err, sizeof err);
  if (!h) {
    fprintf(stderr, "gi-server: %s\n", err);
    return 1;
  }
  int bound = gs_http_port(h);
  if (args.port_file && write_port_file(args.port_file, bound)) {
    fprintf(stderr, "gi-server: --port-file: cannot write '%s': %s\n", args.port_file, strerror(errno));
    stop_service(h, &svc, &cat, &cfg); /* the private folder too, not left for the next start */
    return 1;
  }
  announce(&cfg, &cat, bound);
  int sig = 0;
  sigwait(&sigs, &sig);
  fprintf(stderr, "gi-server: %s: stopping: jobs cancelled, requests given shutdown_grace_s\n", gs_signal_name(sig));
  gs_shutdown_begin(&svc, &sigs);
  stop_service(h, &svc, &cat, &cfg);
  return 0;
}
