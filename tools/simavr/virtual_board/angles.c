/*
 * What the six sensors measure, as the raw 14-bit counts they report. Two sources, applied in
 * time order, each holding its last value (sample and hold):
 *   - a replay schedule loaded from a file (optionally looping);
 *   - live updates pushed through the live channel, each due at a board time.
 * The counts in force are looked up when a sensor is selected (it latches its angle then).
 */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "vb.h"

#define LIVE_QUEUE 65536   /* a power of two */

typedef struct {
	vb_cycles_t at;
	uint16_t counts[VB_ENCODERS];
} update_t;

static uint16_t current[VB_ENCODERS];

static update_t *replay;
static size_t replay_n, replay_next;
static int replay_loop;
static vb_cycles_t replay_period, replay_offset;

static update_t live[LIVE_QUEUE];
static size_t live_head, live_tail;   /* push at head, pop at tail */

void angles_init(const uint16_t rest[VB_ENCODERS])
{
	memcpy(current, rest, sizeof current);
}

static uint32_t le32(const unsigned char *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

void angles_load_replay(const char *path, int loop)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		vb_die("cannot read the replay file %s: %s", path, strerror(errno));
	unsigned char head[12];
	if (fread(head, 1, sizeof head, f) != sizeof head || memcmp(head, "D6RP", 4) != 0)
		vb_die("%s is not a replay file (no D6RP header)", path);
	if (le32(head + 4) != 1)
		vb_die("%s: replay format version %u, this board reads 1", path, le32(head + 4));
	size_t n = le32(head + 8);
	if (n == 0)
		vb_die("%s: the replay has no samples", path);
	replay = calloc(n, sizeof *replay);
	if (!replay)
		vb_die("%s: out of memory for %zu samples", path, n);
	double previous = -1.0;
	for (size_t i = 0; i < n; i++) {
		unsigned char rec[20];
		if (fread(rec, 1, sizeof rec, f) != sizeof rec)
			vb_die("%s: truncated after %zu of %zu samples", path, i, n);
		double t;
		memcpy(&t, rec, 8);   /* little-endian host (x86, arm64) */
		if (!(t >= 0.0) || t < previous)
			vb_die("%s: sample %zu: time %g is negative or goes back", path, i, t);
		previous = t;
		replay[i].at = vb_cycles_of_seconds(t);
		for (int j = 0; j < VB_ENCODERS; j++) {
			uint16_t c = (uint16_t)(rec[8 + 2 * j] | rec[9 + 2 * j] << 8);
			if (c > 0x3FFF && c != VB_NO_ANSWER)
				vb_die("%s: sample %zu: count %u of encoder %d is not 14 bits", path, i, c, j + 1);
			replay[i].counts[j] = c;
		}
	}
	fclose(f);
	replay_n = n;
	replay_loop = loop;
	/* One more sample period after the last sample before the loop starts over. */
	vb_cycles_t last_step = n > 1 ? replay[n - 1].at - replay[n - 2].at : vb_cycles_of_seconds(0.001);
	replay_period = replay[n - 1].at + last_step;
	memcpy(current, replay[0].counts, sizeof current);
}

static int angles_queue_space(void)
{
	return (int)(LIVE_QUEUE - 1 - ((live_head - live_tail) & (LIVE_QUEUE - 1)));
}

int angles_push(vb_cycles_t at, const uint16_t counts[VB_ENCODERS])
{
	if (angles_queue_space() == 0)
		return -1;
	live[live_head].at = at;
	memcpy(live[live_head].counts, counts, sizeof live[live_head].counts);
	live_head = (live_head + 1) & (LIVE_QUEUE - 1);
	return 0;
}

void angles_at(vb_cycles_t now, uint16_t out[VB_ENCODERS])
{
	while (replay_n) {
		if (replay_next == replay_n) {
			if (!replay_loop || replay_period == 0)
				break;
			replay_next = 0;
			replay_offset += replay_period;
		}
		if (replay[replay_next].at + replay_offset > now)
			break;
		memcpy(current, replay[replay_next].counts, sizeof current);
		replay_next++;
	}
	while (live_tail != live_head && live[live_tail].at <= now) {
		memcpy(current, live[live_tail].counts, sizeof current);
		live_tail = (live_tail + 1) & (LIVE_QUEUE - 1);
	}
	memcpy(out, current, sizeof current);
}
