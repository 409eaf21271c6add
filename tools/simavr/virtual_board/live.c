/*
 * The live channel: a Unix stream socket; clients send lines (docs/virtual-board.md,
 * "Live channel"). Times are board time in seconds (simulated time since the board started),
 * or "now".
 *
 *   counts T C1 C2 C3 C4 C5 C6   from T on, the encoders report these raw counts (0..16383)
 *   fault E KIND T0 T1           encoder E (1..6 or all) fails with KIND (biterror, weak,
 *                                strong, noanswer) for frames latched in [T0, T1) (T1: inf)
 *   clear E                      remove E's faults (1..6 or all)
 *   hang on|off                  test builds: hold the hang pin (the watchdog test)
 *   time                         -> "time SECONDS CYCLES"
 *   stats                        -> "stats {JSON}" (one line)
 *   stats-reset                  -> "ok": start a new measurement window
 *   ping                         -> "pong"
 *
 * counts, fault, clear and hang answer nothing unless they are malformed ("error ..."), so a
 * driver can stream updates; a query ("time") answered means everything before it was
 * applied. When the update queue is full the socket is not read (the writer waits).
 */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "vb.h"

#define MAX_CLIENTS 8
#define LINE_MAX_LEN 512

typedef struct {
	int fd;
	char buf[LINE_MAX_LEN];
	size_t len;
	int discarding;   /* a line longer than LINE_MAX_LEN: skip to its end */
} client_t;

static int listener = -1;
static char socket_path[sizeof(((struct sockaddr_un *)0)->sun_path)];
static client_t clients[MAX_CLIENTS];
static uint64_t lines, errors;

static void reply(client_t *c, const char *text)
{
	size_t n = strlen(text);
	while (n) {
		ssize_t w = send(c->fd, text, n, MSG_NOSIGNAL);
		if (w < 0 && errno == EAGAIN) {
			struct pollfd p = {c->fd, POLLOUT, 0};
			if (poll(&p, 1, 1000) <= 0)
				return;
			continue;
		}
		if (w <= 0)
			return;
		text += w;
		n -= (size_t)w;
	}
}

static void fail(client_t *c, const char *why, const char *line)
{
	char text[LINE_MAX_LEN + 128];
	errors++;
	snprintf(text, sizeof text, "error %s: %s\n", why, line);
	reply(c, text);
}

static int parse_time(const char *s, vb_cycles_t *out)
{
	if (!strcmp(s, "now")) {
		*out = vb_avr->cycle;
		return 0;
	}
	if (!strcmp(s, "inf")) {
		*out = UINT64_MAX;
		return 0;
	}
	char *end;
	double t = strtod(s, &end);
	if (*end || !isfinite(t) || t < 0)
		return -1;
	*out = vb_cycles_of_seconds(t);
	return 0;
}

static int parse_encoder(const char *s)
{
	if (!strcmp(s, "all"))
		return -1;
	char *end;
	long e = strtol(s, &end, 10);
	return (*end || e < 1 || e > VB_ENCODERS) ? -2 : (int)e - 1;
}

/* Returns 0 if the line was handled, 1 if it must wait (the update queue is full). */
static int handle(client_t *c, char *line)
{
	char copy[LINE_MAX_LEN];
	snprintf(copy, sizeof copy, "%s", line);
	char *argv[10];
	int argc = 0;
	for (char *tok = strtok(line, " \t\r"); tok && argc < 10; tok = strtok(NULL, " \t\r"))
		argv[argc++] = tok;
	if (argc == 0)
		return 0;
	if (!strcmp(argv[0], "counts")) {
		if (argc != 8)
			return fail(c, "counts takes a time and six counts", copy), 0;
		vb_cycles_t at;
		uint16_t counts[VB_ENCODERS];
		if (parse_time(argv[1], &at))
			return fail(c, "bad time", copy), 0;
		for (int j = 0; j < VB_ENCODERS; j++) {
			char *end;
			long v = strtol(argv[2 + j], &end, 10);
			if (*end || v < 0 || v > 16383)
				return fail(c, "a count is 0..16383", copy), 0;
			counts[j] = (uint16_t)v;
		}
		if (angles_push(at, counts))
			return 1;
	} else if (!strcmp(argv[0], "fault")) {
		if (argc != 5)
			return fail(c, "fault takes an encoder, a kind and two times", copy), 0;
		int e = parse_encoder(argv[1]);
		int kind = vb_fault_parse(argv[2]);
		vb_cycles_t from, to;
		if (e == -2 || kind < 0 || parse_time(argv[3], &from) || parse_time(argv[4], &to))
			return fail(c, "bad fault (encoder 1..6|all, kind biterror|weak|strong|noanswer)",
			            copy), 0;
		for (int j = 0; j < VB_ENCODERS; j++)
			if ((e < 0 || e == j) && encoders_add_fault(j, kind, from, to))
				return fail(c, "too many fault windows", copy), 0;
	} else if (!strcmp(argv[0], "clear")) {
		int e = argc == 2 ? parse_encoder(argv[1]) : -2;
		if (e == -2)
			return fail(c, "clear takes an encoder (1..6|all)", copy), 0;
		encoders_clear_faults(e);
	} else if (!strcmp(argv[0], "hang")) {
		if (argc != 2 || (strcmp(argv[1], "on") && strcmp(argv[1], "off")))
			return fail(c, "hang takes on or off", copy), 0;
		encoders_set_test_pin(!strcmp(argv[1], "on"));
	} else if (!strcmp(argv[0], "time")) {
		char text[128];
		snprintf(text, sizeof text, "time %.9f %llu\n", vb_seconds(vb_avr->cycle),
		         (unsigned long long)vb_avr->cycle);
		reply(c, text);
	} else if (!strcmp(argv[0], "stats")) {
		char *text = NULL;
		size_t size = 0;
		FILE *f = open_memstream(&text, &size);
		fputs("stats ", f);
		vb_report_json(f);
		fputc('\n', f);
		fclose(f);
		reply(c, text);
		free(text);
	} else if (!strcmp(argv[0], "stats-reset")) {
		stats_reset();
		reply(c, "ok\n");
	} else if (!strcmp(argv[0], "ping")) {
		reply(c, "pong\n");
	} else {
		fail(c, "unknown command", copy);
	}
	lines++;
	return 0;
}

void live_init(const char *path)
{
	struct sockaddr_un addr;
	memset(&addr, 0, sizeof addr);
	addr.sun_family = AF_UNIX;
	if (strlen(path) >= sizeof addr.sun_path)
		vb_die("live socket path too long: %s", path);
	struct stat st;
	if (stat(path, &st) == 0) {
		if (!S_ISSOCK(st.st_mode))
			vb_die("%s exists and is not a socket", path);
		unlink(path);   /* left over from an earlier run */
	}
	snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path);
	listener = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
	if (listener < 0 || bind(listener, (struct sockaddr *)&addr, sizeof addr) ||
	    listen(listener, 4))
		vb_die("cannot listen on %s: %s", path, strerror(errno));
	snprintf(socket_path, sizeof socket_path, "%s", path);
	for (int i = 0; i < MAX_CLIENTS; i++)
		clients[i].fd = -1;
}

static void serve(client_t *c)
{
	for (;;) {
		/* lines already buffered first (one may have waited for queue space) */
		char *nl = memchr(c->buf, '\n', c->len);
		if (nl) {
			*nl = '\0';
			size_t used = (size_t)(nl - c->buf) + 1;
			if (c->discarding) {
				c->discarding = 0;
			} else {
				char line[LINE_MAX_LEN];
				memcpy(line, c->buf, used);
				if (handle(c, line)) {
					*nl = '\n';   /* the queue is full: try again next time */
					return;
				}
			}
			memmove(c->buf, c->buf + used, c->len - used);
			c->len -= used;
			continue;
		}
		if (c->len == sizeof c->buf - 1) {   /* an overlong line */
			c->discarding = 1;
			c->len = 0;
		}
		ssize_t n = recv(c->fd, c->buf + c->len, sizeof c->buf - 1 - c->len, 0);
		if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
			close(c->fd);
			c->fd = -1;
			c->len = 0;
			return;
		}
		if (n < 0)
			return;
		c->len += (size_t)n;
	}
}

void live_service(void)
{
	if (listener < 0)
		return;
	for (;;) {
		int fd = accept4(listener, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
		if (fd < 0)
			break;
		int slot = -1;
		for (int i = 0; i < MAX_CLIENTS && slot < 0; i++)
			if (clients[i].fd < 0)
				slot = i;
		if (slot < 0) {
			close(fd);
			continue;
		}
		clients[slot].fd = fd;
		clients[slot].len = 0;
		clients[slot].discarding = 0;
	}
	for (int i = 0; i < MAX_CLIENTS; i++)
		if (clients[i].fd >= 0)
			serve(&clients[i]);
}

int live_fill_fds(void *pollfds, int max)
{
	struct pollfd *p = pollfds;
	int n = 0;
	if (listener < 0)
		return 0;   /* no live channel (and the client table was never set up) */
	if (n < max)
		p[n++] = (struct pollfd){listener, POLLIN, 0};
	for (int i = 0; i < MAX_CLIENTS && n < max; i++)
		if (clients[i].fd >= 0)
			p[n++] = (struct pollfd){clients[i].fd, POLLIN, 0};
	return n;
}

void live_close(void)
{
	for (int i = 0; i < MAX_CLIENTS; i++)
		if (clients[i].fd >= 0)
			close(clients[i].fd);
	if (listener >= 0) {
		close(listener);
		unlink(socket_path);
	}
	listener = -1;
}
