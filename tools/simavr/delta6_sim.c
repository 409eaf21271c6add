/*
 * delta6_sim: run an AVR ELF in simavr and record what the firmware reports.
 *
 *   delta6_sim FIRMWARE.elf [--mcu atmega328p] [--freq 16000000]
 *              [--uart FILE] [--markers FILE] [--max-cycles N] [--stop-marker V]
 *
 * Two channels, both timestamped by the simulator rather than by the firmware:
 *   - markers: every write to GPIOR0 is logged as "<cycle> <value>" (one line each), with the
 *     cycle counter at the write. The firmware brackets the code it wants timed with two
 *     writes, so the cost of timing is one `out` instruction, and nothing else is disturbed.
 *   - UART0 output: every byte the firmware transmits is appended, raw, to the --uart file.
 * The run ends when the firmware writes --stop-marker (default 0xFF) to GPIOR0 (exit 0),
 * when --max-cycles elapse (exit 3), or when the core stops or crashes (exit 4).
 * Bad arguments or an unreadable ELF exit with status 2 and one line on stderr.
 *
 * Kept small on purpose: the virtual board (encoder emulation, pty) builds on the same
 * pattern (IRQ callbacks on pins and the UART), see docs/firmware.md.
 */
#include <errno.h>
#include <getopt.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_io.h>

/* GPIOR0 is I/O register 0x1E on the ATmega48/88/168/328 family: data address 0x3E. */
#define GPIOR0_DATA_ADDR 0x3E

typedef struct {
	FILE *markers;
	FILE *uart;
	int stop_marker;
	int stopped;
} run_state_t;

static void die_usage(const char *msg, const char *arg)
{
	fprintf(stderr, "delta6_sim: error: %s%s%s\n", msg, arg ? ": " : "", arg ? arg : "");
	exit(2);
}

static void on_gpior0_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	run_state_t *st = (run_state_t *)param;
	avr->data[addr] = v; /* an io write hook must store the value itself */
	if (st->markers)
		fprintf(st->markers, "%llu %u\n", (unsigned long long)avr->cycle, v);
	if (v == st->stop_marker)
		st->stopped = 1;
}

static void on_uart_byte(struct avr_irq_t *irq, uint32_t value, void *param)
{
	(void)irq;
	run_state_t *st = (run_state_t *)param;
	if (st->uart)
		fputc((int)(value & 0xFF), st->uart);
}

static unsigned long long parse_number(const char *text, const char *what)
{
	char *end = NULL;
	errno = 0;
	unsigned long long value = strtoull(text, &end, 0);
	if (errno || end == text || *end != '\0')
		die_usage(what, text);
	return value;
}

static FILE *open_output(const char *path)
{
	FILE *f = fopen(path, "wb");
	if (!f)
		die_usage("cannot write", path);
	return f;
}

int main(int argc, char **argv)
{
	const char *elf_path = NULL, *mcu = "atmega328p";
	unsigned long long freq = 16000000ULL, max_cycles = 2000000000ULL;
	run_state_t st = {NULL, NULL, 0xFF, 0};

	enum { OPT_MCU = 1, OPT_FREQ, OPT_MAX_CYCLES, OPT_STOP_MARKER, OPT_UART, OPT_MARKERS };
	static const struct option options[] = {
		{"mcu", required_argument, NULL, OPT_MCU},
		{"freq", required_argument, NULL, OPT_FREQ},
		{"max-cycles", required_argument, NULL, OPT_MAX_CYCLES},
		{"stop-marker", required_argument, NULL, OPT_STOP_MARKER},
		{"uart", required_argument, NULL, OPT_UART},
		{"markers", required_argument, NULL, OPT_MARKERS},
		{NULL, 0, NULL, 0},
	};
	opterr = 0; /* our own one-line messages */
	for (int opt; (opt = getopt_long(argc, argv, ":", options, NULL)) != -1;) {
		switch (opt) {
		case OPT_MCU:
			mcu = optarg;
			break;
		case OPT_FREQ:
			freq = parse_number(optarg, "--freq needs a number");
			break;
		case OPT_MAX_CYCLES:
			max_cycles = parse_number(optarg, "--max-cycles needs a number");
			break;
		case OPT_STOP_MARKER:
			st.stop_marker = (int)parse_number(optarg, "--stop-marker needs a number");
			break;
		case OPT_UART:
			st.uart = open_output(optarg);
			break;
		case OPT_MARKERS:
			st.markers = open_output(optarg);
			break;
		case ':':
			die_usage("option needs a value", argv[optind - 1]);
			break;
		default:
			die_usage("unknown option", argv[optind - 1]);
		}
	}
	if (optind < argc)
		elf_path = argv[optind];
	if (optind + 1 < argc)
		die_usage("more than one firmware file given", argv[optind + 1]);
	if (!elf_path)
		die_usage("no firmware file given", NULL);

	elf_firmware_t fw;
	memset(&fw, 0, sizeof fw);
	if (elf_read_firmware(elf_path, &fw) != 0)
		die_usage("cannot read ELF firmware", elf_path);
	snprintf(fw.mmcu, sizeof fw.mmcu, "%s", mcu);
	fw.frequency = (uint32_t)freq;

	avr_t *avr = avr_make_mcu_by_name(fw.mmcu);
	if (!avr)
		die_usage("simavr does not know this MCU", fw.mmcu);
	avr_init(avr);
	avr->log = LOG_ERROR;
	avr_load_firmware(avr, &fw);

	/* Raw UART capture: no line-buffered console echo, no pacing against the wall clock. */
	uint32_t flags = 0;
	avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
	avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
	                        on_uart_byte, &st);
	avr_register_io_write(avr, GPIOR0_DATA_ADDR, on_gpior0_write, &st);

	int status = 0;
	for (;;) {
		int state = avr_run(avr);
		if (st.stopped)
			break;
		if (state == cpu_Done || state == cpu_Crashed) {
			fprintf(stderr, "delta6_sim: error: firmware %s at cycle %llu\n",
			        state == cpu_Done ? "stopped" : "crashed",
			        (unsigned long long)avr->cycle);
			status = 4;
			break;
		}
		if (avr->cycle >= max_cycles) {
			fprintf(stderr, "delta6_sim: error: no stop marker after %llu cycles\n",
			        (unsigned long long)avr->cycle);
			status = 3;
			break;
		}
	}
	if (st.markers)
		fclose(st.markers);
	if (st.uart)
		fclose(st.uart);
	avr_terminate(avr);
	return status;
}
