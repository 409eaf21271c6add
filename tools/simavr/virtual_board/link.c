/*
 * The firmware's UART on a pseudo-terminal of our own (not simavr's uart_pty part, whose fixed
 * symlink name makes parallel runs collide).
 *
 * - The pty is raw (no echo, no line editing) from the start. We open and close its slave
 *   once, so that the master reports a hang-up until a client opens the slave: that is how
 *   we see a client come and go.
 * - Output: every byte the firmware writes to UDR goes to the client. With no client the bytes
 *   are dropped (and counted), as a USB bridge with a closed port drops them; a new client
 *   never gets stale bytes. A slow client: in a paced run the queue (1 MiB) absorbs it and
 *   overflow is dropped and counted; in an unpaced run the simulation waits for the reader.
 * - Input: bytes from the client go into the UART one character time apart (simavr's UART
 *   takes one byte per 11 bit times; its 64-byte receive FIFO must never overflow), and only
 *   once the firmware has finished setup() (bytes sent during a reboot wait, not lost).
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include <simavr/avr_uart.h>
#include <simavr/sim_cycle_timers.h>
#include <simavr/sim_io.h>

#include "vb.h"

#define OUT_SIZE (1u << 20)   /* powers of two */
#define IN_SIZE (1u << 16)

static int master = -1;
static char pty_name[256];
static int present;
static int ready;
static vb_cycles_t in_char_cycles;
static avr_irq_t *uart_in;
static int feeding;

static uint8_t *out_buf;
static size_t out_head, out_tail;
static uint8_t in_buf[IN_SIZE];
static size_t in_head, in_tail;

static struct {
	uint64_t out, in, dropped_no_client, dropped_overflow, clients, stale_in;
} count;

static size_t out_fill(void) { return (out_head - out_tail) & (OUT_SIZE - 1); }
static size_t in_fill(void) { return (in_head - in_tail) & (IN_SIZE - 1); }

static void on_uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	(void)param;
	count.out++;
	stats_uart_byte(vb_avr->cycle);
	if (!present) {
		count.dropped_no_client++;
		return;
	}
	if (out_fill() == OUT_SIZE - 1) {
		count.dropped_overflow++;
		return;
	}
	out_buf[out_head] = (uint8_t)value;
	out_head = (out_head + 1) & (OUT_SIZE - 1);
}

static avr_cycle_count_t feed_one(avr_t *avr, avr_cycle_count_t when, void *param)
{
	(void)avr;
	(void)param;
	if (!ready || in_fill() == 0) {
		feeding = 0;
		return 0;
	}
	avr_raise_irq(uart_in, in_buf[in_tail]);
	in_tail = (in_tail + 1) & (IN_SIZE - 1);
	count.in++;
	return when + in_char_cycles;   /* called again one character later */
}

static void start_feeding(void)
{
	if (feeding || !ready || in_fill() == 0)
		return;
	feeding = 1;
	avr_cycle_timer_register(vb_avr, 1, feed_one, NULL);
}

void link_set_ready(int r)
{
	ready = r;
	start_feeding();
}

void link_init(uint32_t baud)
{
	out_buf = malloc(OUT_SIZE);
	if (!out_buf)
		vb_die("out of memory");
	master = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
	if (master < 0 || grantpt(master) || unlockpt(master) ||
	    ptsname_r(master, pty_name, sizeof pty_name))
		vb_die("cannot create a pseudo-terminal: %s", strerror(errno));
	struct termios t;
	if (tcgetattr(master, &t) == 0) {
		cfmakeraw(&t);
		tcsetattr(master, TCSANOW, &t);
	}
	int slave = open(pty_name, O_RDWR | O_NOCTTY);
	if (slave >= 0)
		close(slave);   /* from now on the master sees a hang-up while no client is there */

	/* simavr's UART takes a byte every 1e6 / (baud / 11) us (it counts a parity bit). */
	uint32_t us = 1000000u / (baud / 11u);
	in_char_cycles = (vb_cycles_t)(us + 1) * vb_avr->frequency / 1000000u;

	uint32_t flags = 0;   /* no stdio echo, no sleeping in the UART model */
	avr_ioctl(vb_avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
	avr_irq_register_notify(avr_io_getirq(vb_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
	                        on_uart_out, NULL);
	uart_in = avr_io_getirq(vb_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
}

const char *link_pty_name(void) { return pty_name; }
int link_fd(void) { return master; }

int link_client_present(void)
{
	struct pollfd p = {master, POLLIN, 0};
	if (poll(&p, 1, 0) < 0)
		return present;
	int now_present = !(p.revents & POLLHUP);
	if (now_present && !present)
		count.clients++;
	if (!now_present && present) {
		/* the client left: what it did not read, and what it had sent, belong to it */
		out_head = out_tail = 0;
		count.stale_in += in_fill();
		in_head = in_tail = 0;
	}
	present = now_present;
	return present;
}

static void read_input(void)
{
	uint8_t buf[4096];
	for (;;) {
		size_t space = IN_SIZE - 1 - in_fill();
		if (space == 0)
			return;
		ssize_t n = read(master, buf, space < sizeof buf ? space : sizeof buf);
		if (n <= 0)
			return;
		for (ssize_t i = 0; i < n; i++) {
			in_buf[in_head] = buf[i];
			in_head = (in_head + 1) & (IN_SIZE - 1);
		}
	}
}

/* Write what is queued; returns 0 when done or the client is gone, 1 if the pty is full. */
static int write_output(void)
{
	while (out_fill() && present) {
		size_t chunk = out_head >= out_tail ? out_head - out_tail : OUT_SIZE - out_tail;
		ssize_t n = write(master, out_buf + out_tail, chunk);
		if (n > 0) {
			out_tail = (out_tail + (size_t)n) & (OUT_SIZE - 1);
			continue;
		}
		if (n < 0 && errno == EAGAIN)
			return 1;
		link_client_present();   /* EIO: the client went away */
		return 0;
	}
	return 0;
}

void link_service(int blocking)
{
	if (!link_client_present())
		return;
	read_input();
	start_feeding();
	while (write_output() && blocking) {
		struct pollfd p = {master, POLLOUT, 0};
		poll(&p, 1, 100);
		if (!link_client_present())
			break;
	}
}

void link_flush(double timeout_s)
{
	int waited_ms = 0;
	while (link_client_present() && write_output() && waited_ms < timeout_s * 1000) {
		struct pollfd p = {master, POLLOUT, 0};
		poll(&p, 1, 10);
		waited_ms += 10;
	}
}

void link_json(FILE *f)
{
	fprintf(f, "{\"pty\": \"%s\", \"client\": %s, \"clients\": %llu, \"bytes_out\": %llu, "
	        "\"bytes_in\": %llu, \"dropped_no_client\": %llu, \"dropped_overflow\": %llu, "
	        "\"queued_out\": %zu, \"queued_in\": %zu, \"discarded_in\": %llu}",
	        pty_name, present ? "true" : "false", (unsigned long long)count.clients,
	        (unsigned long long)count.out, (unsigned long long)count.in,
	        (unsigned long long)count.dropped_no_client,
	        (unsigned long long)count.dropped_overflow, out_fill(), in_fill(),
	        (unsigned long long)count.stale_in);
}

void link_close(void)
{
	if (master >= 0)
		close(master);
	master = -1;
}
