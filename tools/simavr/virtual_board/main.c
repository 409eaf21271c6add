/*
 * delta6_vboard: the Delta6 virtual board (docs/virtual-board.md).
 *
 *   delta6_vboard FIRMWARE.elf [options]
 *     --freq HZ             CPU clock (16000000)
 *     --baud N              the firmware's UART rate, for timing figures (500000)
 *     --replay FILE         encoder counts over time (the D6RP file delta6 writes)
 *     --loop                start the replay over at its end
 *     --live SOCKET         listen for live updates and queries on this Unix socket
 *     --rest C1,...,C6      counts reported before any update (default 0,0,0,0,0,0)
 *     --fault E:KIND:T0:T1  encoder E (1..6) fails with KIND for T0 <= t < T1 (board seconds;
 *                           T1 may be inf); repeatable
 *     --eeprom FILE         EEPROM image: loaded at start if it exists, saved at exit
 *     --stats FILE          timing and counters as JSON at exit
 *     --read-log FILE       one line per encoder scan: cycle, six counts, six fault kinds,
 *                           mask of complete frames
 *     --ram-dump FILE       the SRAM at exit (0x100..RAMEND; simavr starts it zeroed, so the
 *                           lowest non-zero byte above the static data bounds the stack depth)
 *     --speed X             1 = real time (default), 2 = twice as fast, 0 = as fast as it runs
 *     --duration S          stop after S seconds of board time
 *     --no-wait             start at once instead of waiting for a client on the pty
 *     --bus-timing H,S,V    sensor timing in ns: clock half period, select setup, data valid
 *                           (board_contract.h's D6_BUS_*_NS: the firmware's own)
 *     --parent PID          end the run (as on SIGTERM) when the process PID is gone: the
 *                           board dies with the program that started it, even on SIGKILL
 *
 * stdout carries exactly one line, "pty PATH", once the port exists. The simulation starts when
 * a client opens it (and either sends a byte or has had 0.5 s to flush its input), so nothing
 * the board says at boot is flushed away. SIGINT/SIGTERM end the run: the client gets what is
 * queued, the EEPROM and the statistics are saved, exit status 0. Bad options or files exit 2
 * with one line on stderr, and so does an EEPROM image that cannot be saved at the end; a
 * firmware crash exits 4.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <simavr/avr_eeprom.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_io.h>

#include "../../../firmware/src/board_contract.h"
#include "vb.h"

#define EEPROM_SIZE 1024   /* ATmega328P */
#define MAX_FAULTS 64

avr_t *vb_avr;
static volatile sig_atomic_t stop_requested;
static FILE *protocol_out;   /* the original stdout: simavr prints chatter on stdout */
static double wall_start;
static vb_cycles_t duration_cycles;

static void say(const char *prefix, const char *fmt, va_list ap)
{
	fprintf(stderr, "delta6_vboard: %s", prefix);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
}

void vb_die(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	say("error: ", fmt, ap);
	va_end(ap);
	exit(2);
}

void vb_warn(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	say("", fmt, ap);
	va_end(ap);
}

double vb_seconds(vb_cycles_t cycles) { return (double)cycles / vb_avr->frequency; }

vb_cycles_t vb_cycles_of_seconds(double seconds)
{
	return (vb_cycles_t)llround(seconds * vb_avr->frequency);
}

double vb_now_wall(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* simavr sleeps in wall time while the CPU sleeps; we pace the whole run ourselves. */
static void no_wall_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
	(void)avr;
	(void)how_long;
}

static void on_signal(int sig)
{
	(void)sig;
	stop_requested = 1;
}

void vb_report_json(FILE *f)
{
	fprintf(f, "{\"board_seconds\": %.6f, \"wall_seconds\": %.3f, \"timing\": ",
	        vb_seconds(vb_avr->cycle), vb_now_wall() - wall_start);
	stats_json(f);
	fputs(", \"encoders\": ", f);
	encoders_json(f);
	fputs(", \"link\": ", f);
	link_json(f);
	fputs("}", f);
}

typedef struct {
	const char *elf, *replay, *live, *eeprom, *stats, *read_log, *ram_dump;
	uint32_t freq, baud;
	long parent;
	int loop, no_wait;
	double speed, duration;
	uint16_t rest[VB_ENCODERS];
	vb_bus_timing_t timing;
	struct {
		int e, kind;
		double from, to;
	} faults[MAX_FAULTS];
	int n_faults;
} options_t;

static double parse_double(const char *s, const char *what)
{
	char *end;
	errno = 0;
	double v = strtod(s, &end);
	if (errno || end == s || *end || isnan(v))
		vb_die("%s takes a number, got %s", what, s);
	return v;
}

static int parse_list(const char *s, long *out, int n, char sep)
{
	const char *p = s;
	for (int i = 0; i < n; i++) {
		char *end;
		errno = 0;
		out[i] = strtol(p, &end, 10);
		if (errno || end == p)
			return -1;
		if (i < n - 1 && *end != sep)
			return -1;
		p = end + 1;
		if (i == n - 1 && *end)
			return -1;
	}
	return 0;
}

static void parse_fault(options_t *o, char *spec)
{
	char *fields[4];
	int n = 0;
	for (char *tok = strtok(spec, ":"); tok && n < 4; tok = strtok(NULL, ":"))
		fields[n++] = tok;
	if (n != 4 || strtok(NULL, ":"))
		vb_die("--fault takes E:KIND:T0:T1, e.g. 3:weak:1.0:1.5");
	if (o->n_faults == MAX_FAULTS)
		vb_die("at most %d --fault options", MAX_FAULTS);
	char *end;
	long e = strtol(fields[0], &end, 10);
	if (*end || e < 1 || e > VB_ENCODERS)
		vb_die("--fault: encoder %s is not 1..6", fields[0]);
	int kind = vb_fault_parse(fields[1]);
	if (kind < 0)
		vb_die("--fault: kind %s is not biterror, weak, strong or noanswer", fields[1]);
	double from = parse_double(fields[2], "--fault T0");
	double to = strcmp(fields[3], "inf") ? parse_double(fields[3], "--fault T1") : INFINITY;
	if (from < 0 || !(to > from))
		vb_die("--fault: the window %s..%s is empty or negative", fields[2], fields[3]);
	o->faults[o->n_faults].e = (int)e - 1;
	o->faults[o->n_faults].kind = kind;
	o->faults[o->n_faults].from = from;
	o->faults[o->n_faults].to = to;
	o->n_faults++;
}

static void parse_options(options_t *o, int argc, char **argv)
{
	memset(o, 0, sizeof *o);
	o->freq = 16000000;
	o->baud = 500000;
	o->speed = 1.0;
	o->timing = (vb_bus_timing_t){D6_BUS_HALF_PERIOD_NS, D6_BUS_SELECT_SETUP_NS,
	                              D6_BUS_DATA_VALID_NS};
	enum {
		OPT_LOOP = 1, OPT_NO_WAIT, OPT_FREQ, OPT_BAUD, OPT_REPLAY, OPT_LIVE, OPT_EEPROM,
		OPT_STATS, OPT_READ_LOG, OPT_RAM_DUMP, OPT_SPEED, OPT_DURATION, OPT_REST, OPT_FAULT,
		OPT_BUS_TIMING, OPT_PARENT,
	};
	static const struct option options[] = {
		{"loop", no_argument, NULL, OPT_LOOP},
		{"no-wait", no_argument, NULL, OPT_NO_WAIT},
		{"freq", required_argument, NULL, OPT_FREQ},
		{"baud", required_argument, NULL, OPT_BAUD},
		{"replay", required_argument, NULL, OPT_REPLAY},
		{"live", required_argument, NULL, OPT_LIVE},
		{"eeprom", required_argument, NULL, OPT_EEPROM},
		{"stats", required_argument, NULL, OPT_STATS},
		{"read-log", required_argument, NULL, OPT_READ_LOG},
		{"ram-dump", required_argument, NULL, OPT_RAM_DUMP},
		{"speed", required_argument, NULL, OPT_SPEED},
		{"duration", required_argument, NULL, OPT_DURATION},
		{"rest", required_argument, NULL, OPT_REST},
		{"fault", required_argument, NULL, OPT_FAULT},
		{"bus-timing", required_argument, NULL, OPT_BUS_TIMING},
		{"parent", required_argument, NULL, OPT_PARENT},
		{NULL, 0, NULL, 0},
	};
	opterr = 0; /* our own one-line messages */
	for (int opt; (opt = getopt_long(argc, argv, ":", options, NULL)) != -1;) {
		char *v = optarg;
		switch (opt) {
		case OPT_LOOP:
			o->loop = 1;
			break;
		case OPT_NO_WAIT:
			o->no_wait = 1;
			break;
		case OPT_FREQ:
			o->freq = (uint32_t)parse_double(v, "--freq");
			break;
		case OPT_BAUD:
			o->baud = (uint32_t)parse_double(v, "--baud");
			break;
		case OPT_REPLAY:
			o->replay = v;
			break;
		case OPT_LIVE:
			o->live = v;
			break;
		case OPT_EEPROM:
			o->eeprom = v;
			break;
		case OPT_STATS:
			o->stats = v;
			break;
		case OPT_READ_LOG:
			o->read_log = v;
			break;
		case OPT_RAM_DUMP:
			o->ram_dump = v;
			break;
		case OPT_SPEED:
			o->speed = parse_double(v, "--speed");
			if (o->speed < 0)
				vb_die("--speed must be >= 0");
			break;
		case OPT_DURATION:
			o->duration = parse_double(v, "--duration");
			if (!(o->duration > 0))
				vb_die("--duration must be positive");
			break;
		case OPT_REST: {
			long c[VB_ENCODERS];
			if (parse_list(v, c, VB_ENCODERS, ','))
				vb_die("--rest takes six counts separated by commas");
			for (int j = 0; j < VB_ENCODERS; j++) {
				if (c[j] < 0 || c[j] > 16383)
					vb_die("--rest: count %ld is not 0..16383", c[j]);
				o->rest[j] = (uint16_t)c[j];
			}
			break;
		}
		case OPT_FAULT:
			parse_fault(o, v);
			break;
		case OPT_PARENT:
			o->parent = (long)parse_double(v, "--parent");
			break;
		case OPT_BUS_TIMING: {
			long t[3];
			if (parse_list(v, t, 3, ',') || t[0] <= 0 || t[1] <= 0 || t[2] <= 0)
				vb_die("--bus-timing takes three positive times in ns: HALF,SETUP,VALID");
			o->timing = (vb_bus_timing_t){(uint32_t)t[0], (uint32_t)t[1], (uint32_t)t[2]};
			break;
		}
		case ':':
			vb_die("%s needs a value", argv[optind - 1]);
			break;
		default:
			vb_die("unknown option %s", argv[optind - 1]);
		}
	}
	if (optind < argc)
		o->elf = argv[optind];
	if (optind + 1 < argc)
		vb_die("more than one firmware file given: %s", argv[optind + 1]);
	if (!o->elf)
		vb_die("no firmware file given");
	if (o->baud < 1000 || o->freq < 1000000)
		vb_die("implausible --freq or --baud");
}

/* simavr's EEPROM, directly: its ioctls return -1 on success too, and some versions refuse
 * a transfer of the whole size; asked with no buffer, GET hands out the memory itself. */
static uint8_t *eeprom_memory(void)
{
	avr_eeprom_desc_t d = {.ee = NULL, .offset = 0, .size = 0};
	avr_ioctl(vb_avr, AVR_IOCTL_EEPROM_GET, &d);
	if (!d.ee)
		vb_die("simavr has no EEPROM for this MCU");
	return d.ee;
}

static void load_eeprom(const char *path)
{
	FILE *f = fopen(path, "rb");
	if (!f) {
		if (errno == ENOENT)
			return;   /* a new board: erased EEPROM */
		vb_die("cannot read the EEPROM image %s: %s", path, strerror(errno));
	}
	uint8_t image[EEPROM_SIZE];
	size_t n = fread(image, 1, sizeof image, f);
	int extra = fgetc(f) != EOF;
	fclose(f);
	if (n != sizeof image || extra)
		vb_die("%s is not a %d-byte EEPROM image", path, EEPROM_SIZE);
	memcpy(eeprom_memory(), image, EEPROM_SIZE);
}

/* Returns 0, or -1 (said on stderr): a configuration the firmware saved must not be lost
 * without the run failing. */
static int save_eeprom(const char *path)
{
	char tmp[4096];
	snprintf(tmp, sizeof tmp, "%s.partial", path);
	FILE *f = fopen(tmp, "wb");
	if (!f || fwrite(eeprom_memory(), 1, EEPROM_SIZE, f) != EEPROM_SIZE || fclose(f) != 0 ||
	    rename(tmp, path) != 0) {
		vb_warn("error: could not save the EEPROM image %s: %s", path, strerror(errno));
		return -1;
	}
	return 0;
}

/* The program that started us is gone (killed, even by SIGKILL): stop as on SIGTERM. A
 * getppid() per millisecond of board time costs nothing next to the emulation. */
static long parent_pid;

static void check_parent(void)
{
	if (parent_pid > 0 && getppid() != parent_pid)
		stop_requested = 1;
}

static void write_ram(const char *path)
{
	FILE *f = fopen(path, "wb");
	size_t n = (size_t)vb_avr->ramend + 1 - 0x100;
	if (!f || fwrite(vb_avr->data + 0x100, 1, n, f) != n || fclose(f) != 0)
		vb_warn("cannot write the RAM dump %s: %s", path, strerror(errno));
}

static void write_stats(const char *path)
{
	char tmp[4096];
	snprintf(tmp, sizeof tmp, "%s.partial", path);
	FILE *f = fopen(tmp, "w");
	if (!f) {
		vb_warn("cannot write %s: %s", path, strerror(errno));
		return;
	}
	vb_report_json(f);
	fputc('\n', f);
	if (fclose(f) != 0 || rename(tmp, path) != 0)
		vb_warn("cannot write %s: %s", path, strerror(errno));
}

/* Wait for a client on the pty, then for it to settle: a byte from it, or 0.5 s. (Polling
 * the master while no client is there returns at once with a hang-up: sleep instead.) */
static void wait_for_client(void)
{
	while (!stop_requested && !link_client_present()) {
		usleep(20000);
		check_parent();
	}
	double settle_until = vb_now_wall() + 0.5;
	while (!stop_requested && vb_now_wall() < settle_until) {
		struct pollfd p = {link_fd(), POLLIN, 0};
		if (poll(&p, 1, 10) > 0 && (p.revents & POLLIN))
			break;
		check_parent();
	}
}

/* Sleep until the wall clock catches up with the board (speed > 0), serving I/O meanwhile. */
static void pace(double speed, vb_cycles_t start_cycle, double start_wall)
{
	double due = start_wall + vb_seconds(vb_avr->cycle - start_cycle) / speed;
	for (;;) {
		double wait = due - vb_now_wall();
		if (wait <= 0 || stop_requested)
			return;
		struct pollfd fds[16];
		int n = 0;
		if (link_client_present())   /* without a client the master only says "hang-up" */
			fds[n++] = (struct pollfd){link_fd(), POLLIN, 0};
		n += live_fill_fds(fds + n, 16 - n);
		struct timespec ts = {(time_t)wait, (long)((wait - (time_t)wait) * 1e9)};
		if (ppoll(fds, (nfds_t)n, &ts, NULL) > 0) {
			link_service(0);
			live_service();
		}
	}
}

int main(int argc, char **argv)
{
	options_t o;
	parse_options(&o, argc, argv);

	/* simavr prints progress on stdout; keep stdout for our one line. */
	int out_fd = dup(1);
	dup2(2, 1);
	protocol_out = fdopen(out_fd, "w");

	elf_firmware_t fw;
	memset(&fw, 0, sizeof fw);
	if (elf_read_firmware(o.elf, &fw) != 0)
		vb_die("cannot read the firmware %s", o.elf);
	snprintf(fw.mmcu, sizeof fw.mmcu, "atmega328p");
	fw.frequency = o.freq;
	vb_avr = avr_make_mcu_by_name(fw.mmcu);
	if (!vb_avr)
		vb_die("simavr does not know the atmega328p");
	avr_init(vb_avr);
	vb_avr->log = LOG_ERROR;
	vb_avr->sleep = no_wall_sleep;
	avr_load_firmware(vb_avr, &fw);
	if (o.eeprom)
		load_eeprom(o.eeprom);

	angles_init(o.rest);
	if (o.replay)
		angles_load_replay(o.replay, o.loop);
	encoders_init(&o.timing, o.read_log);
	for (int i = 0; i < o.n_faults; i++) {
		vb_cycles_t to = isinf(o.faults[i].to) ? UINT64_MAX : vb_cycles_of_seconds(o.faults[i].to);
		encoders_add_fault(o.faults[i].e, o.faults[i].kind,
		                   vb_cycles_of_seconds(o.faults[i].from), to);
	}
	stats_init(o.baud);
	link_init(o.baud);
	if (o.live)
		live_init(o.live);
	duration_cycles = o.duration > 0 ? vb_cycles_of_seconds(o.duration) : 0;

	struct sigaction sa;
	memset(&sa, 0, sizeof sa);
	sa.sa_handler = on_signal;
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	signal(SIGPIPE, SIG_IGN);
	parent_pid = o.parent;
	check_parent();   /* gone before we got here */

	fprintf(protocol_out, "pty %s\n", link_pty_name());
	fflush(protocol_out);
	wall_start = vb_now_wall();
	if (!o.no_wait)
		wait_for_client();

	int status = 0;
	const vb_cycles_t slice = o.freq / 1000;   /* service I/O every millisecond of board time */
	vb_cycles_t start_cycle = vb_avr->cycle;
	double start_wall = vb_now_wall();
	wall_start = start_wall;
	stats_reset();
	while (!stop_requested) {
		vb_cycles_t slice_end = vb_avr->cycle + slice;
		while (vb_avr->cycle < slice_end) {
			int state = avr_run(vb_avr);
			if (state == cpu_Done || state == cpu_Crashed) {
				vb_warn("error: the firmware %s at %.6f s",
				        state == cpu_Done ? "stopped" : "crashed", vb_seconds(vb_avr->cycle));
				status = 4;
				stop_requested = 1;
				break;
			}
		}
		link_service(o.speed == 0);
		live_service();
		check_parent();
		if (duration_cycles && vb_avr->cycle >= duration_cycles)
			break;
		if (o.speed > 0)
			pace(o.speed, start_cycle, start_wall);
	}

	link_flush(1.0);
	usleep(200000);   /* let the client read the last bytes before the pty goes away */
	if (o.eeprom && save_eeprom(o.eeprom) != 0 && status == 0)
		status = 2;
	if (o.stats)
		write_stats(o.stats);
	if (o.ram_dump)
		write_ram(o.ram_dump);
	encoders_close();
	live_close();
	link_close();
	avr_terminate(vb_avr);
	return status;
}
