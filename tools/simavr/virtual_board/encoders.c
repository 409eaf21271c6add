/*
 * Six emulated ERCK-05SPI encoders at the bit level, wired as board_contract.h says: a shared
 * clock, one chip select and one half-duplex data line each.
 *
 * A sensor, as we read the published firmware (docs/virtual-board.md, "The encoder model"):
 *   - selecting it (chip select falls) latches its angle;
 *   - it samples the master's 16 command bits on rising clock edges (0x55FF, msb first);
 *   - after the 16th falling edge it drives its line, and after every falling edge it puts
 *     out the next of 32 bits (word, then inverse, msb first), each data_valid_ns late;
 *   - deselecting it releases the line.
 * Timing checks (counted, reported as violations): chip select to first clock, clock high
 * and low times, data setup before the rising edge, the master sampling a bit before it was
 * valid. Bus contention: the master driving a line that a sensor drives (from either side).
 * Faults per encoder and time window: bit error, weak or strong field, no answer.
 */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <simavr/avr_ioport.h>
#include <simavr/sim_cycle_timers.h>
#include <simavr/sim_io.h>
#include <simavr/sim_irq.h>

#include "../../../firmware/src/board_contract.h"
#include "vb.h"

/* ATmega328P: the data address of PINC. simavr keeps an input pin's value there, but only
 * updates it when the pin's IRQ value changes; writing the bit as well keeps the two in step
 * across a chip reset (which clears the register and not the IRQ). */
#define PINC_ADDR 0x26
#define COMMAND D6_ENCODER_COMMAND
#define COMMAND_BITS D6_ENCODER_COMMAND_BITS
#define FRAME_BITS (COMMAND_BITS + 32)   /* then the word and its inverse */
#define MAX_WINDOWS 256

const char *const vb_fault_names[VB_FAULT_KINDS] = {"none", "biterror", "weak", "strong",
                                                    "noanswer"};

int vb_fault_parse(const char *name)
{
	for (int k = 1; k < VB_FAULT_KINDS; k++)
		if (!strcmp(name, vb_fault_names[k]))
			return k;
	return -1;
}

typedef struct {
	vb_cycles_t from, to;
	int kind;
} window_t;

typedef struct {
	int selected;
	int bits;              /* rising edges while selected: 0..48 */
	uint16_t command;
	uint32_t frame;        /* what it sends, first bit in bit 31 */
	int fault;
	int answering;
	int driving, level;
	int pending, pending_level;
	vb_cycles_t pending_at;
	vb_cycles_t selected_at;
	uint16_t count;
	window_t windows[MAX_WINDOWS];
	int n_windows;
	/* counters */
	uint64_t frames, complete, aborted, bad_commands, faulted[VB_FAULT_KINDS];
} sensor_t;

static sensor_t sensors[VB_ENCODERS];
static avr_irq_t *data_irq[VB_ENCODERS];
static avr_irq_t *test_irq;
static vb_cycles_t half_min, setup_min, data_valid;
static int clk;
static vb_cycles_t last_rise, last_fall;
static int clock_seen;
static vb_cycles_t data_changed_at[VB_ENCODERS];
static uint8_t last_port_c;
static unsigned flip_counter;
static uint8_t ext_c_mask, ext_c_value, ext_b_mask, ext_b_value;

static struct {
	uint64_t select_setup, clock_low, clock_high, data_setup, data_valid, extra_clocks;
} violations;
static struct {
	uint64_t events;
	vb_cycles_t first;
} contention;

/* The read log: one line per scan (all sensors selected together, then released). */
static FILE *read_log;
static int scan_open;
static vb_cycles_t scan_at;
static uint16_t scan_counts[VB_ENCODERS];
static int scan_faults[VB_ENCODERS];
static unsigned scan_complete;
static uint64_t scans;

static void set_external(char port, uint8_t mask, uint8_t value)
{
	avr_ioport_external_t e;
	memset(&e, 0, sizeof e);
	e.name = port;
	e.mask = mask;
	e.value = value;
	avr_ioctl(vb_avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(port), &e);
}

static avr_ioport_state_t port_state(char port)
{
	avr_ioport_state_t s;
	memset(&s, 0, sizeof s);
	avr_ioctl(vb_avr, AVR_IOCTL_IOPORT_GETSTATE(port), &s);
	return s;
}

static void note_contention(void)
{
	if (contention.events++ == 0)
		contention.first = vb_avr->cycle;
}

/* Put `level` on the line of sensor j as the AVR sees it when the pin is an input. */
static void line_to_avr(int j, int level)
{
	uint8_t bit = (uint8_t)(1u << (D6_328P_DATA_SHIFT + j));
	if (level)
		vb_avr->data[PINC_ADDR] |= bit;
	else
		vb_avr->data[PINC_ADDR] &= (uint8_t)~bit;
	avr_raise_irq(data_irq[j], (uint32_t)level);
}

static void drive(int j, int level)
{
	sensor_t *s = &sensors[j];
	uint8_t bit = (uint8_t)(1u << (D6_328P_DATA_SHIFT + j));
	if (port_state('C').ddr & bit)
		note_contention();   /* the master still drives this line */
	s->driving = 1;
	s->level = level;
	ext_c_mask |= bit;
	ext_c_value = (uint8_t)(level ? (ext_c_value | bit) : (ext_c_value & ~bit));
	set_external('C', ext_c_mask, ext_c_value);
	line_to_avr(j, level);
}

static void release(int j)
{
	sensor_t *s = &sensors[j];
	uint8_t bit = (uint8_t)(1u << (D6_328P_DATA_SHIFT + j));
	s->pending = 0;
	if (!s->driving)
		return;
	s->driving = 0;
	ext_c_mask &= (uint8_t)~bit;
	ext_c_value &= (uint8_t)~bit;
	set_external('C', ext_c_mask, ext_c_value);
	avr_ioport_state_t st = port_state('C');
	if (!(st.ddr & bit) && (st.port & bit))
		line_to_avr(j, 1);   /* the pull-up takes over; without one the line holds */
}

static avr_cycle_count_t apply_pending(avr_t *avr, avr_cycle_count_t when, void *param)
{
	(void)avr;
	(void)when;
	(void)param;
	for (int j = 0; j < VB_ENCODERS; j++) {
		sensor_t *s = &sensors[j];
		if (s->pending && s->pending_at <= vb_avr->cycle) {
			s->pending = 0;
			drive(j, s->pending_level);
		}
	}
	return 0;
}

static int fault_at(const sensor_t *s, vb_cycles_t now)
{
	for (int i = 0; i < s->n_windows; i++)
		if (now >= s->windows[i].from && now < s->windows[i].to)
			return s->windows[i].kind;
	return VB_FAULT_NONE;
}

static void scan_begin(vb_cycles_t now)
{
	scan_open = 1;
	scan_at = now;
	scan_complete = 0;
	memset(scan_faults, 0, sizeof scan_faults);
	memset(scan_counts, 0, sizeof scan_counts);
}

static void scan_end(void)
{
	scan_open = 0;
	scans++;
	if (!read_log)
		return;
	fprintf(read_log, "%llu", (unsigned long long)scan_at);
	for (int j = 0; j < VB_ENCODERS; j++)
		fprintf(read_log, " %u", scan_counts[j]);
	for (int j = 0; j < VB_ENCODERS; j++)
		fprintf(read_log, " %d", scan_faults[j]);
	fprintf(read_log, " %u\n", scan_complete);
}

static int any_selected(void)
{
	for (int j = 0; j < VB_ENCODERS; j++)
		if (sensors[j].selected)
			return 1;
	return 0;
}

static void on_select(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	int j = (int)(intptr_t)param;
	sensor_t *s = &sensors[j];
	vb_cycles_t now = vb_avr->cycle;
	if (!value && !s->selected) {
		if (!any_selected())
			scan_begin(now);
		uint16_t counts[VB_ENCODERS];
		angles_at(now, counts);
		s->selected = 1;
		s->selected_at = now;
		s->bits = 0;
		s->command = 0;
		s->answering = 0;
		s->fault = fault_at(s, now);
		if (counts[j] == VB_NO_ANSWER) {   /* the replayed log had no angle here */
			if (s->fault == VB_FAULT_NONE)
				s->fault = VB_FAULT_NOANSWER;
		} else {
			s->count = counts[j];
		}
		s->frame = vb_frame(s->count, s->fault, flip_counter++);
		s->frames++;
		s->faulted[s->fault]++;
		scan_counts[j] = s->count;
		scan_faults[j] = s->fault;
	} else if (value && s->selected) {
		s->selected = 0;
		if (s->bits == FRAME_BITS) {
			s->complete++;
			scan_complete |= 1u << j;
		} else {
			s->aborted++;
		}
		release(j);
		if (scan_open && !any_selected())
			scan_end();
	}
}

static int master_level(int j)
{
	avr_ioport_state_t st = port_state('C');
	uint8_t bit = (uint8_t)(1u << (D6_328P_DATA_SHIFT + j));
	if (st.ddr & bit)
		return !!(st.port & bit);
	return !!(vb_avr->data[PINC_ADDR] & bit);
}

static void on_clock(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	(void)param;
	vb_cycles_t now = vb_avr->cycle;
	int level = value ? 1 : 0;
	if (level == clk)
		return;
	clk = level;
	if (level) {
		if (clock_seen && now - last_fall < half_min && any_selected())
			violations.clock_low++;
		for (int j = 0; j < VB_ENCODERS; j++) {
			sensor_t *s = &sensors[j];
			if (!s->selected)
				continue;
			if (s->bits == 0 && now - s->selected_at < setup_min)
				violations.select_setup++;
			if (s->bits < COMMAND_BITS) {
				if (now - data_changed_at[j] < half_min)
					violations.data_setup++;
				s->command = (uint16_t)((s->command << 1) | master_level(j));
				if (++s->bits == COMMAND_BITS) {
					s->answering = s->command == COMMAND && s->fault != VB_FAULT_NOANSWER;
					if (s->command != COMMAND)
						s->bad_commands++;
				}
			} else if (s->bits < FRAME_BITS) {
				if (s->answering && s->pending)
					violations.data_valid++;   /* sampled before the bit was out */
				s->bits++;
			} else {
				violations.extra_clocks++;
			}
		}
		last_rise = now;
	} else {
		if (clock_seen && now - last_rise < half_min && any_selected())
			violations.clock_high++;
		int scheduled = 0;
		for (int j = 0; j < VB_ENCODERS; j++) {
			sensor_t *s = &sensors[j];
			if (!s->selected || !s->answering || s->bits < COMMAND_BITS || s->bits >= FRAME_BITS)
				continue;
			int k = s->bits - COMMAND_BITS;
			s->pending = 1;
			s->pending_level = (int)((s->frame >> (31 - k)) & 1u);
			s->pending_at = now + data_valid;
			scheduled = 1;
		}
		if (scheduled)
			avr_cycle_timer_register(vb_avr, data_valid, apply_pending, NULL);
		last_fall = now;
	}
	clock_seen = 1;
}

static void on_data_direction(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	(void)param;
	for (int j = 0; j < VB_ENCODERS; j++) {
		uint8_t bit = (uint8_t)(1u << (D6_328P_DATA_SHIFT + j));
		if (sensors[j].driving && (value & bit))
			note_contention();
	}
}

static void on_data_port(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	(void)param;
	uint8_t changed = (uint8_t)(value ^ last_port_c);
	for (int j = 0; j < VB_ENCODERS; j++)
		if (changed & (1u << (D6_328P_DATA_SHIFT + j)))
			data_changed_at[j] = vb_avr->cycle;
	last_port_c = (uint8_t)value;
}

static vb_cycles_t cycles_of_ns(uint32_t ns)
{
	/* rounded up: a minimum stays a minimum */
	return ((vb_cycles_t)ns * vb_avr->frequency + 999999999ull) / 1000000000ull;
}

void encoders_init(const vb_bus_timing_t *timing, const char *read_log_path)
{
	half_min = cycles_of_ns(timing->half_period_ns);
	setup_min = cycles_of_ns(timing->select_setup_ns);
	data_valid = cycles_of_ns(timing->data_valid_ns);
	if (data_valid == 0)
		data_valid = 1;
	for (int j = 0; j < VB_ENCODERS; j++) {
		avr_irq_t *cs = avr_io_getirq(vb_avr, AVR_IOCTL_IOPORT_GETIRQ(D6_328P_CS_PORT),
		                              D6_328P_CS_SHIFT + j);
		avr_irq_register_notify(cs, on_select, (void *)(intptr_t)j);
		data_irq[j] = avr_io_getirq(vb_avr, AVR_IOCTL_IOPORT_GETIRQ(D6_328P_DATA_PORT),
		                            D6_328P_DATA_SHIFT + j);
	}
	avr_irq_register_notify(avr_io_getirq(vb_avr, AVR_IOCTL_IOPORT_GETIRQ(D6_328P_CLK_PORT),
	                                      D6_328P_CLK_BIT), on_clock, NULL);
	avr_irq_register_notify(avr_io_getirq(vb_avr, AVR_IOCTL_IOPORT_GETIRQ(D6_328P_DATA_PORT),
	                                      IOPORT_IRQ_DIRECTION_ALL), on_data_direction, NULL);
	avr_irq_register_notify(avr_io_getirq(vb_avr, AVR_IOCTL_IOPORT_GETIRQ(D6_328P_DATA_PORT),
	                                      IOPORT_IRQ_REG_PORT), on_data_port, NULL);
	test_irq = avr_io_getirq(vb_avr, AVR_IOCTL_IOPORT_GETIRQ(D6_328P_TEST_PORT), D6_328P_TEST_BIT);
	if (read_log_path) {
		read_log = fopen(read_log_path, "w");
		if (!read_log)
			vb_die("cannot write the read log %s: %s", read_log_path, strerror(errno));
	}
}

int encoders_add_fault(int e, int kind, vb_cycles_t from, vb_cycles_t to)
{
	if (e < 0 || e >= VB_ENCODERS || kind <= VB_FAULT_NONE || kind >= VB_FAULT_KINDS)
		return -1;
	sensor_t *s = &sensors[e];
	if (s->n_windows == MAX_WINDOWS)
		return -1;
	s->windows[s->n_windows].from = from;
	s->windows[s->n_windows].to = to;
	s->windows[s->n_windows].kind = kind;
	s->n_windows++;
	return 0;
}

void encoders_clear_faults(int e)
{
	for (int j = 0; j < VB_ENCODERS; j++)
		if (e < 0 || e == j)
			sensors[j].n_windows = 0;
}

void encoders_set_test_pin(int low)
{
	uint8_t bit = (uint8_t)(1u << D6_328P_TEST_BIT);
	ext_b_mask = low ? (uint8_t)(ext_b_mask | bit) : (uint8_t)(ext_b_mask & ~bit);
	ext_b_value &= (uint8_t)~bit;
	set_external('B', ext_b_mask, ext_b_value);
	avr_raise_irq(test_irq, low ? 0 : 1);
}

void encoders_close(void)
{
	if (read_log) {
		if (scan_open)
			scan_end();
		fclose(read_log);
		read_log = NULL;
	}
}

void encoders_json(FILE *f)
{
	uint64_t frames = 0, complete = 0, aborted = 0, bad = 0;
	uint64_t faulted[VB_FAULT_KINDS] = {0};
	for (int j = 0; j < VB_ENCODERS; j++) {
		frames += sensors[j].frames;
		complete += sensors[j].complete;
		aborted += sensors[j].aborted;
		bad += sensors[j].bad_commands;
		for (int k = 0; k < VB_FAULT_KINDS; k++)
			faulted[k] += sensors[j].faulted[k];
	}
	fprintf(f, "{\"scans\": %llu, \"frames\": %llu, \"complete\": %llu, \"aborted\": %llu, "
	        "\"bad_commands\": %llu, \"faulted\": {",
	        (unsigned long long)scans, (unsigned long long)frames, (unsigned long long)complete,
	        (unsigned long long)aborted, (unsigned long long)bad);
	for (int k = 1; k < VB_FAULT_KINDS; k++)
		fprintf(f, "%s\"%s\": %llu", k > 1 ? ", " : "", vb_fault_names[k],
		        (unsigned long long)faulted[k]);
	fprintf(f, "}, \"violations\": {\"select_setup\": %llu, \"clock_low\": %llu, "
	        "\"clock_high\": %llu, \"data_setup\": %llu, \"data_valid\": %llu, "
	        "\"extra_clocks\": %llu}, \"contention\": %llu, \"contention_first_cycle\": %llu, "
	        "\"timing_ns\": {\"half_period\": %llu, \"select_setup\": %llu, \"data_valid\": %llu}}",
	        (unsigned long long)violations.select_setup, (unsigned long long)violations.clock_low,
	        (unsigned long long)violations.clock_high, (unsigned long long)violations.data_setup,
	        (unsigned long long)violations.data_valid, (unsigned long long)violations.extra_clocks,
	        (unsigned long long)contention.events, (unsigned long long)contention.first,
	        (unsigned long long)(half_min * 1000000000ull / vb_avr->frequency),
	        (unsigned long long)(setup_min * 1000000000ull / vb_avr->frequency),
	        (unsigned long long)(data_valid * 1000000000ull / vb_avr->frequency));
}
