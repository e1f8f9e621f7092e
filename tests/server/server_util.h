/* server_util.h: a real gi-server on loopback for the tests in tests/server/.
 *
 * Starts gi-server from a config text on an ephemeral port (its log in
 * DIR/server.log), speaks HTTP with libcurl, and opens raw sockets for what
 * libcurl will not send (bad framing, a byte at a time). */
#ifndef GI_SERVER_UTIL_H
#define GI_SERVER_UTIL_H

#include <curl/curl.h>
#include <stddef.h>
#include <sys/types.h>

#define SU_TOKEN "test-token-0123456789abcdef"

typedef struct {
  pid_t pid;
  int port;
  char dir[512];
} su_server;

typedef struct {
  long status;
  char *body;
  size_t len;
  char headers[8192];
  size_t hlen;
} su_resp;

void su_sleep_ms(int ms);
double su_now_ms(void);
/* Writes DIR/gi-server.ini (and token.txt) under tu_tmpdir()/name, starts
 * gi-server and waits for its port; 0 or -1. */
int su_start(su_server *s, const char *name, const char *ini);
/* Sends sig and waits up to wait_ms for the exit; returns the exit status
 * (128 + signal when killed), -2 on timeout (then SIGKILL), and the time
 * it took in *ms (may be NULL). */
int su_signal_wait(su_server *s, int sig, int wait_ms, double *ms);
/* SIGTERM and the exit status (0 = clean shutdown). */
int su_stop(su_server *s);
/* Whether requests follow redirects (default 1: a viewpoint URL's 307 to
 * its cell URL is followed, and r holds the final answer's headers). */
extern int su_follow_redirects;
/* An easy handle for one request into r (for curl_multi); *hdrs is the
 * caller's to free with curl_slist_free_all after the transfer. */
CURL *su_make_req(const su_server *s, const char *method, const char *path, const char *body, const char *token,
                  su_resp *r, struct curl_slist **hdrs);
/* One request (method NULL = GET, token NULL = none); fails the test when
 * curl cannot complete it. */
su_resp su_http(const su_server *s, const char *method, const char *path, const char *body, const char *token);
/* A header's value (case-insensitive name), or NULL. A per-thread buffer, valid until the thread's next call. */
const char *su_header(const su_resp *r, const char *name);
/* Asserts an error answer: status, a JSON error body (Content-Type too), its name, and needle in its message. */
void su_expect_error(const su_resp *r, long status, const char *name, const char *needle);
/* A counter or gauge from /metrics (sum over label sets when labels is NULL). */
double su_metric(const su_server *s, const char *name, const char *labels);
/* Writes r's body to the server's folder as name; returns the path
 * (static buffer, valid until the next call). Fails the test on error. */
const char *su_save_body(const su_server *s, const su_resp *r, const char *name);
/* r's body saved as name and read back as an EXR (caller frees). */
struct gi_exr_file *su_read_exr(const su_server *s, const su_resp *r, const char *name);
/* The server's resident memory (VmRSS) in MiB, or -1. */
double su_rss_mb(const su_server *s);
/* A TCP connection to the server from source address src (NULL: any); -1 on error. */
int su_connect(const su_server *s, const char *src);
/* Reads what the server sends within ms milliseconds (or until it closes)
 * into buf (NUL-terminated); returns the byte count, -1 on error. */
long su_read(int fd, char *buf, size_t size, int ms);
/* Sends req as it is on a new connection and returns what the server
 * answers within ms (a static buffer of 8 KiB, overwritten by the next
 * call; not thread-safe). */
const char *su_raw(const su_server *s, const char *req, int ms);

#endif
