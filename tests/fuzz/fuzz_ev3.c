// SPDX-License-Identifier: GPL-2.0
/*
 * libFuzzer target: the EV3 UART protocol core (ev3_uart_proto.c), driven
 * the way the sensor core (ev3_uart_core.c) drives it.
 *
 * Input: a 4-byte little-endian "host" seed, then the bytes the sensor
 * sends. Seed 0 is a quiet host: the stream is received in one batch, the
 * host answers the handshake at once and does nothing else. Any other seed
 * drives a pseudo-random host: batches of 1 to 64 bytes, line errors
 * (framing, parity, break), keep-alive ticks, SELECTs and WRITEs, bytes
 * arriving between the sensor's ACK and the host's speed change, failed
 * registrations, fast sync probes (SPEED 115200) that the bytes may answer
 * or not. After every call the parser's state is checked against
 * what its header promises, and every event against the state. One input
 * in four also goes through differential(): the bytes in batches against
 * the same bytes one at a time.
 *
 * A custom mutator keeps most checksums right (see the end of this file).
 */
#include <errno.h>
#include <string.h>

#include "ev3_uart_chan.h"
#include "ev3_uart_proto.h"
#include "fuzz_check.h"

struct host {
	struct ev3_uart_parser *p;
	/* The IIO channels ev3_uart_iio.c would register for the sensor. */
	struct ev3_uart_chan chans[EV3_UART_MAX_CHANS + 1];
	unsigned int num_chans;
	u32 rng;		/* xorshift32 state; 0: the quiet host */
	unsigned int acked_wait;	/* batches to receive before start_data */
	unsigned int probe_wait;	/* batches to receive before probe_end */
	s64 now;
	s64 last_ts;
	s64 registered_at;	/* h->now at the last handshake */
	struct ev3_uart_backoff backoff;
	unsigned long events;
};

static u32 rnd(struct host *h)
{
	h->rng ^= h->rng << 13;
	h->rng ^= h->rng >> 17;
	h->rng ^= h->rng << 5;
	return h->rng;
}

static void check_string(const char *s, size_t size, size_t max, bool empty_ok)
{
	size_t n = strnlen(s, size), i;

	CHECK(n < size);
	CHECK(n <= max);
	CHECK(empty_ok || n > 0);
	for (i = 0; i < n; i++)
		CHECK(s[i] >= 0x20 && s[i] <= 0x7e);
}

static void check_mode(const struct ev3_uart_mode *m)
{
	unsigned int size = ev3_uart_data_size(m->data_type);

	check_string(m->name, sizeof(m->name), EV3_UART_NAME_LEN, false);
	check_string(m->units, sizeof(m->units), EV3_UART_UNITS_LEN, true);
	CHECK(m->data_type <= EV3_UART_DATA_FLOAT && size);
	CHECK(m->num_values >= 1);
	CHECK(m->num_values * size <= EV3_UART_MAX_PAYLOAD);
	CHECK(m->figures <= EV3_UART_MAX_FIGURES);
	CHECK(m->decimals <= EV3_UART_MAX_DECIMALS);
}

static void check_parser(const struct ev3_uart_parser *p)
{
	const struct ev3_uart_sensor *s = &p->sensor;

	CHECK(p->state <= EV3_UART_STATE_PROBE);
	/* 2400 baud, or the probe's speed from the probe on. */
	CHECK(p->sync_speed == EV3_UART_SPEED_MIN ||
	      p->sync_speed == EV3_UART_SPEED_FAST);
	CHECK(p->msg_len <= EV3_UART_MAX_MSG_LEN);
	CHECK(p->replay_pos <= p->replay_len);
	CHECK(p->replay_len <= EV3_UART_MAX_MSG_LEN);
	CHECK(p->info_mode == EV3_UART_NO_MODE || p->info_mode < EV3_UART_MAX_MODES);
	/* EXT_MODE (Powered Up) adds 0 or 8 to the mode of a DATA header. */
	CHECK(p->ext_mode == 0 || p->ext_mode == EV3_UART_MAX_EV3_MODES);
	CHECK(s->num_combos <= EV3_UART_MAX_COMBOS);
	if (p->state == EV3_UART_STATE_SYNC) {
		CHECK(p->msg_len <= 3);
		return;
	}
	/*
	 * Waiting for the probe's ACK: the TYPE hunt's window at most (it
	 * goes on at 2400), nothing to replay.
	 */
	if (p->state == EV3_UART_STATE_PROBE) {
		CHECK(p->sync_speed == EV3_UART_SPEED_FAST);
		CHECK(p->msg_len <= 3 && p->replay_pos == p->replay_len);
		return;
	}
	/* A message being received: its header and length agree. */
	if ((p->state == EV3_UART_STATE_INFO || p->state == EV3_UART_STATE_DATA) &&
	    p->msg_len) {
		CHECK(p->msg_size == ev3_uart_msg_len(p->msg[0]));
		CHECK(p->msg_len < p->msg_size);
		CHECK(p->msg_size <= EV3_UART_MAX_MSG_LEN);
	}
	CHECK(s->type >= EV3_UART_TYPE_MIN && s->type <= EV3_UART_TYPE_MAX);
	CHECK(s->num_modes >= 1 && s->num_modes <= EV3_UART_MAX_MODES);
	CHECK(s->num_view_modes >= 1 && s->num_view_modes <= s->num_modes);
	CHECK(s->speed >= EV3_UART_SPEED_MIN && s->speed <= EV3_UART_SPEED_MAX);
	if (p->state == EV3_UART_STATE_INFO) {
		CHECK(p->info_mode == EV3_UART_NO_MODE || p->info_mode < s->num_modes);
		CHECK(p->msg_len < EV3_UART_MAX_MSG_LEN);
		return;
	}
	/* ACKED and DATA: the description is complete (checked in full by
	 * check_description(), at the handshake and at the end: it does not
	 * change in between, but per event that would cost half the time).
	 */
	CHECK((p->modes_done & ((1U << s->num_modes) - 1)) ==
	      (1U << s->num_modes) - 1);
	if (p->state == EV3_UART_STATE_DATA) {
		CHECK(p->mode < s->num_modes);
		/* Only a device that spoke the Powered Up grammar sends EXT_MODE. */
		CHECK(!p->ext_mode || s->lump);
		/* Modes 8 and up only with more than 8 modes, which needs it. */
		CHECK(s->num_modes <= EV3_UART_MAX_EV3_MODES || s->lump);
		CHECK(p->pending_mode == EV3_UART_NO_MODE ||
		      p->pending_mode < s->num_modes);
		CHECK(p->data_err <= EV3_UART_MAX_DATA_ERR);
		CHECK(p->silent_ticks <= EV3_UART_MAX_DATA_ERR);
		CHECK(p->msg_len < EV3_UART_MAX_PAYLOAD + 2);
	}
}

/*
 * What the LED view and an IIO buffer of several modes make of a
 * description: the lights' mode takes their values; a combination found
 * for a run of channels has all their modes, and its values fit one
 * message, one after the other; the WRITE that sets it up is well formed.
 */
static void check_lights_and_combos(struct host *h)
{
	const struct ev3_uart_sensor *s = &h->p->sensor;
	struct ev3_uart_combo_entry e[EV3_UART_MAX_COMBO_ENTRIES + 1];
	u8 msg[EV3_UART_COMBO_MSG_LEN], mode = EV3_UART_NO_MODE;
	unsigned int i, j, n, len, modes;
	int ret, combo, off, prev;

	for (i = 0; i < EV3_UART_MAX_MODES + 1; i++) {
		ret = ev3_uart_lump_data_len(s, i);
		CHECK(ret == -EINVAL || (ret >= 1 && ret <= EV3_UART_MAX_PAYLOAD &&
					 i < s->num_modes && s->lump &&
					 s->modes[i].mapping_out));
	}
	n = ev3_uart_lump_lights(s, &mode);
	CHECK(n <= EV3_UART_MAX_LIGHTS);
	if (n) {
		CHECK(mode < s->num_modes);
		CHECK(ev3_uart_lump_data_len(s, mode) == (int)n);
	}
	for (i = 0; i < h->num_chans; i++) {
		n = 1 + (i + h->num_chans) % (EV3_UART_MAX_COMBO_ENTRIES + 1);
		if (i + n > h->num_chans)
			break;
		modes = 0;
		for (j = 0; j < n; j++) {
			e[j].mode = h->chans[i + j].mode;
			e[j].index = h->chans[i + j].index;
			modes |= 1U << e[j].mode;
		}
		combo = ev3_uart_combo_find(s, e, n, &len);
		if (combo < 0) {
			CHECK(combo == -EINVAL);
			continue;
		}
		CHECK(s->lump && n <= EV3_UART_MAX_COMBO_ENTRIES);
		CHECK(combo < s->num_combos && (s->combos[combo] & modes) == modes);
		CHECK(len >= n && len <= EV3_UART_MAX_PAYLOAD);
		for (j = 0, prev = -1; j < n; j++) {
			off = ev3_uart_combo_offset(s, e, n, j);
			CHECK(off > prev && off < (int)len);
			prev = off;
		}
		CHECK(prev + (int)ev3_uart_data_size(s->modes[e[n - 1].mode].data_type) ==
		      (int)len);
		ret = ev3_uart_build_combo(msg, combo, e, n);
		CHECK(ret >= (int)n + 4 && ret <= EV3_UART_COMBO_MSG_LEN);
		CHECK(ret == (int)ev3_uart_msg_len(msg[0]));
		CHECK(msg[1] == (EV3_UART_COMBO_CMD | n) && msg[2] == combo);
		CHECK(msg[ret - 1] == ev3_uart_checksum(msg, ret - 1));
	}
}

/*
 * What ev3_uart_iio.c and the sysfs "modes" and "mode" attributes do with
 * a new sensor's description: every channel within bounds and showable,
 * every mode's token unique and selecting its own mode.
 */
static void build_chans(struct host *h)
{
	const struct ev3_uart_sensor *s = &h->p->sensor;
	char tok[EV3_UART_MAX_MODES][EV3_UART_TOKEN_LEN + 1];
	char ver[EV3_UART_VERSION_LEN + 1];
	unsigned int i, j, n;

	n = ev3_uart_chans_build(s, NULL, 0);
	CHECK(n <= EV3_UART_MAX_CHANS);
	/* A guard after the room given must stay untouched. */
	memset(&h->chans[n], 0x5a, sizeof(h->chans[n]));
	CHECK(ev3_uart_chans_build(s, h->chans, n) == n);
	CHECK(h->chans[n].mode == 0x5a);
	h->num_chans = n;
	for (i = 0; i < n; i++) {
		const struct ev3_uart_chan *c = &h->chans[i];
		const struct ev3_uart_mode *m;
		s64 nano;

		CHECK(c->mode < s->num_modes);
		m = &s->modes[c->mode];
		CHECK(c->index < m->num_values);
		CHECK(c->realbits == 8 * ev3_uart_data_size(m->data_type));
		CHECK(c->decimals <= m->decimals);
		CHECK(c->decimals == 0 || m->data_type == EV3_UART_DATA_FLOAT);
		/* The parts of a value have one sign; the scale is shown. */
		CHECK(c->scale_val2 > -1000000000 && c->scale_val2 < 1000000000);
		CHECK(c->offset_val2 > -1000000 && c->offset_val2 < 1000000);
		CHECK((c->scale_val >= 0 && c->scale_val2 >= 0) ||
		      (c->scale_val <= 0 && c->scale_val2 <= 0));
		CHECK((c->offset_val >= 0 && c->offset_val2 >= 0) ||
		      (c->offset_val <= 0 && c->offset_val2 <= 0));
		nano = (s64)c->scale_val * 1000000000 + c->scale_val2;
		CHECK(nano >= 1000 || nano <= -1000);
		for (j = 0; j < i; j++)
			CHECK(h->chans[j].mode < c->mode ||
			      (h->chans[j].mode == c->mode && h->chans[j].index < c->index));
	}
	for (i = 0; i < s->num_modes; i++) {
		CHECK(ev3_uart_mode_token(s, i, tok[i], sizeof(tok[i])) >= 1);
		CHECK(!strchr(tok[i], ' '));
		CHECK(ev3_uart_find_mode(s, tok[i]) == (int)i);
		for (j = 0; j < i; j++)
			CHECK(strcmp(tok[i], tok[j]));
	}
	check_lights_and_combos(h);
	/* fw_version in sysfs: always the same width, whatever was sent. */
	CHECK(ev3_uart_version_string(s->fw_version, ver, sizeof(ver)) ==
	      EV3_UART_VERSION_LEN && strlen(ver) == EV3_UART_VERSION_LEN);
}

static void check_description(const struct ev3_uart_parser *p)
{
	unsigned int i;

	check_parser(p);
	if (p->state == EV3_UART_STATE_ACKED || p->state == EV3_UART_STATE_DATA)
		for (i = 0; i < p->sensor.num_modes; i++)
			check_mode(&p->sensor.modes[i]);
}

/* What ev3_uart_iio.c and ev3_uart_class.c do with a DATA message. */
static void use_data(struct host *h, const struct ev3_uart_event *ev,
		     size_t rest)
{
	const struct ev3_uart_parser *p = h->p;
	const struct ev3_uart_mode *m;
	unsigned int i, size;
	s32 v;
	s64 t;
	int ret;

	CHECK(ev->mode < p->sensor.num_modes);
	CHECK(ev->mode == p->mode);
	CHECK(ev->len >= 1 && ev->len <= EV3_UART_MAX_PAYLOAD);
	CHECK((ev->len & (ev->len - 1)) == 0);
	m = &p->sensor.modes[ev->mode];
	size = ev3_uart_data_size(m->data_type);
	CHECK(ev->len >= m->num_values * size);
	for (i = 0; i < m->num_values; i++) {
		ret = ev3_uart_read_value(m, p->data, ev->len, i, &v);
		CHECK(!ret || (ret == -ERANGE && m->data_type == EV3_UART_DATA_FLOAT));
		if (!ret)
			(void)ev3_uart_scale_value(m, v);
	}
	CHECK(ev3_uart_read_value(m, p->data, ev->len, m->num_values, &v) == -ENXIO);
	/* The IIO buffer's scan and the _raw attributes. */
	for (i = 0; i < h->num_chans; i++) {
		if (h->chans[i].mode != ev->mode)
			continue;
		ret = ev3_uart_chan_read(&p->sensor, &h->chans[i], p->data, ev->len, &v);
		CHECK(!ret || (ret == -ERANGE && m->data_type == EV3_UART_DATA_FLOAT));
	}
	/* The class's sysfs reads the whole buffer, whatever the length. */
	for (i = 0; i < m->num_values; i++)
		if (!ev3_uart_read_value(m, p->data, EV3_UART_MAX_PAYLOAD, i, &v))
			(void)ev3_uart_scale_value(m, v);

	/*
	 * The clock moves as the bytes come in (see receive()), so the
	 * estimates must go strictly forward.
	 */
	t = ev3_uart_msg_time(h->now, rest, ev->len + 2, p->sensor.speed, h->last_ts);
	CHECK(!h->last_ts || t > h->last_ts);
	h->last_ts = t;
}

static void start_data(struct host *h)
{
	u8 ack;

	CHECK(ev3_uart_build_ack(&ack) == 1 && ack == EV3_UART_SYS_ACK);
	if (h->rng && rnd(h) % 32 == 0) {
		/* Registration failed: the ldisc starts over. */
		ev3_uart_parser_init(h->p);
		return;
	}
	ev3_uart_parser_start_data(h->p);
	CHECK(h->p->state == EV3_UART_STATE_DATA);
	CHECK(h->p->mode == 0 && h->p->pending_mode == EV3_UART_NO_MODE);
}

/*
 * A sensor lost (ev3_uart_reset()): the back-off of a device that
 * keeps failing (ev3_uart_backoff_lost()), with the time since its
 * handshake.
 */
static void lost(struct host *h)
{
	s64 lived = (h->now - h->registered_at) / 1000000;
	unsigned int before = h->backoff.failures, wait;

	if (lived < 0 || lived > 100000)
		lived = 100000;
	wait = ev3_uart_backoff_lost(&h->backoff, lived);
	CHECK(wait <= EV3_UART_BACKOFF_MAX_MS);
	CHECK(!wait || wait % EV3_UART_BACKOFF_MIN_MS == 0);
	if (lived >= EV3_UART_SHORT_LIFE_MS) {
		CHECK(!wait && !h->backoff.failures);
	} else {
		CHECK(h->backoff.failures >= before);
		CHECK(h->backoff.failures <= EV3_UART_FREE_RETRIES +
					     EV3_UART_BACKOFF_MAX_SHIFT + 1);
		CHECK(!wait == (h->backoff.failures <= EV3_UART_FREE_RETRIES));
	}
}

static void event(struct host *h, const struct ev3_uart_event *ev, size_t rest)
{
	struct ev3_uart_parser *p = h->p;
	const char *name;

	check_parser(p);
	if (ev->type != EV3_UART_EV_NONE)
		h->events++;
	switch (ev->type) {
	case EV3_UART_EV_NONE:
		break;
	case EV3_UART_EV_SYNC:
		CHECK(p->state == EV3_UART_STATE_INFO);
		/* A TYPE during the probe starts a handshake at 2400. */
		CHECK(p->sync_speed == EV3_UART_SPEED_MIN ||
		      p->sensor.speed == EV3_UART_SPEED_FAST);
		break;
	case EV3_UART_EV_HANDSHAKE:
		CHECK(p->state == EV3_UART_STATE_ACKED);
		check_description(p);
		build_chans(h);
		h->last_ts = 0;		/* a new IIO device */
		name = ev3_uart_driver_name(p->sensor.type);
		CHECK(!name || strncmp(name, "lego-ev3-", 9) == 0 ||
		      strncmp(name, "fcl-", 4) == 0);
		CHECK(!name || strlen(name) < EV3_UART_DRIVER_NAME_LEN);
		name = ev3_uart_lump_driver_name(p->sensor.type);
		CHECK(!name || (strncmp(name, "lego-", 5) == 0 &&
				strlen(name) < EV3_UART_DRIVER_NAME_LEN));
		h->registered_at = h->now;
		h->acked_wait = h->rng && rnd(h) % 4 == 0 ? 1 + rnd(h) % 3 : 0;
		if (!h->acked_wait)
			start_data(h);
		break;
	case EV3_UART_EV_DATA:
		CHECK(p->state == EV3_UART_STATE_DATA);
		/* Only the ultrasonic sensor's mode 6 is ever relabelled. */
		CHECK(!ev->us_dc_in ||
		      (p->sensor.type == EV3_UART_TYPE_US && ev->mode == 6));
		use_data(h, ev, rest);
		break;
	case EV3_UART_EV_ERROR:
		CHECK(p->state == EV3_UART_STATE_SYNC);
		CHECK(ev->reason && ev->reason[0]);
		lost(h);
		break;
	case EV3_UART_EV_MSG:
		CHECK(p->report_msgs && p->state == EV3_UART_STATE_INFO);
		CHECK(ev->len >= 3 && ev->len <= EV3_UART_MAX_MSG_LEN);
		break;
	case EV3_UART_EV_FAST:
		/* The probe's ACK: hunting for TYPE at its speed. */
		CHECK(p->state == EV3_UART_STATE_SYNC && !p->msg_len);
		CHECK(p->sync_speed == EV3_UART_SPEED_FAST);
		break;
	default:
		CHECK(0);
	}
	check_parser(p);
}

/* ev3_uart_receive_buf() without line errors, for one batch. */
static void receive(struct host *h, const u8 *buf, size_t count)
{
	struct ev3_uart_event ev;
	unsigned int stuck = 0;
	size_t used;
	u32 speed = h->p->state == EV3_UART_STATE_DATA ? h->p->sensor.speed
						       : h->p->sync_speed;

	/*
	 * The batch is handled after its last byte came in (8N1: 10 bits a
	 * byte), a little late at times.
	 */
	h->now += count * 10000000000LL / speed;
	if (h->rng)
		h->now += rnd(h) % 5000000;
	/* As the driver does while ev3_uart_rx is traced: half the inputs. */
	h->p->report_msgs = h->rng & 4;
	while (count > 0) {
		used = ev3_uart_parser_feed(h->p, buf, count, &ev);
		CHECK(used <= count);
		/* No event: everything was consumed. */
		CHECK(ev.type != EV3_UART_EV_NONE || used == count);
		/* Events without input come from the replay buffer: bounded. */
		stuck = used ? 0 : stuck + 1;
		CHECK(stuck <= EV3_UART_MAX_MSG_LEN);
		buf += used;
		count -= used;
		event(h, &ev, count);
	}
}

/*
 * The fast sync probe (SPEED 115200 sent at 115200), as the ldisc makes it
 * from SYNC at 2400 baud; probe_end() after a few batches.
 */
static void probe(struct host *h)
{
	struct ev3_uart_parser *p = h->p;
	bool can = p->state == EV3_UART_STATE_SYNC &&
		   p->sync_speed == EV3_UART_SPEED_MIN;
	u8 msg[EV3_UART_SPEED_MSG_LEN];

	CHECK(ev3_uart_build_speed(msg, EV3_UART_SPEED_FAST) == sizeof(msg));
	CHECK(ev3_uart_msg_len(msg[0]) == sizeof(msg));
	CHECK(msg[5] == ev3_uart_checksum(msg, 5));
	if (ev3_uart_parser_probe(p, EV3_UART_SPEED_FAST)) {
		CHECK(!can);
		return;
	}
	CHECK(can && p->state == EV3_UART_STATE_PROBE);
	check_parser(p);
	h->probe_wait = 1 + rnd(h) % 4;
}

static void probe_end(struct host *h)
{
	struct ev3_uart_parser *p = h->p;
	bool waiting = p->state == EV3_UART_STATE_PROBE;
	u32 old = p->sync_speed, speed;

	speed = ev3_uart_parser_probe_end(p);
	CHECK(speed == p->sync_speed);
	CHECK(p->state != EV3_UART_STATE_PROBE);
	if (waiting)
		CHECK(speed == EV3_UART_SPEED_MIN && p->state == EV3_UART_STATE_SYNC);
	else
		CHECK(speed == old);
	check_parser(p);
}

/* The host's side of the data phase: SELECT, WRITE, keep-alive. */
static void host_actions(struct host *h)
{
	struct ev3_uart_parser *p = h->p;
	struct ev3_uart_event ev;
	u8 msg[EV3_UART_MAX_PAYLOAD + 5], data[EV3_UART_MAX_PAYLOAD + 1];
	u8 mode;
	size_t len;
	int ret;

	if (rnd(h) % 8 == 0) {
		mode = rnd(h) % (EV3_UART_MAX_MODES + 1);
		ret = ev3_uart_parser_select(p, mode);
		if (p->state != EV3_UART_STATE_DATA)
			CHECK(ret == -ENODEV);
		else if (mode >= p->sensor.num_modes)
			CHECK(ret == -EINVAL);
		else
			CHECK(!ret && p->pending_mode == mode);
		CHECK(ev3_uart_build_select(msg, mode) == 3);
		CHECK(msg[2] == ev3_uart_checksum(msg, 2));
	}
	if (rnd(h) % 16 == 0) {
		len = rnd(h) % (EV3_UART_MAX_PAYLOAD + 2);
		memset(data, 0x5a, sizeof(data));
		ret = ev3_uart_build_write(msg, data, len);
		if (!len || len > EV3_UART_MAX_PAYLOAD) {
			CHECK(ret == -EINVAL);
		} else {
			CHECK(ret >= (int)len + 2 && ret <= EV3_UART_MAX_PAYLOAD + 2);
			CHECK(ret == (int)ev3_uart_msg_len(msg[0]));
			CHECK(msg[ret - 1] == ev3_uart_checksum(msg, ret - 1));
		}
	}
	if (rnd(h) % 16 == 0) {
		/* Powered Up values: EXT_MODE, then DATA. */
		len = rnd(h) % (EV3_UART_MAX_PAYLOAD + 2);
		mode = rnd(h) % (EV3_UART_MAX_MODES + 1);
		ret = ev3_uart_build_lump_data(msg, mode, data, len);
		if (!len || len > EV3_UART_MAX_PAYLOAD || mode >= EV3_UART_MAX_MODES) {
			CHECK(ret == -EINVAL);
		} else {
			CHECK(ret >= (int)len + 5 && ret <= EV3_UART_MAX_PAYLOAD + 5);
			CHECK(msg[0] == EV3_UART_EXT_MODE_HDR && msg[1] == (mode & 8));
			CHECK(msg[2] == ev3_uart_checksum(msg, 2));
			CHECK(ret - 3 == (int)ev3_uart_msg_len(msg[3]));
			CHECK(((msg[3] & EV3_UART_MSG_CMD_MASK) | msg[1]) == mode);
			CHECK(msg[ret - 1] == ev3_uart_checksum(msg + 3, ret - 4));
		}
	}
	if (rnd(h) % 4 == 0) {
		bool lost;

		h->now += 100000000;	/* the keep-alive period */
		lost = ev3_uart_parser_tick(p, &ev);
		CHECK(ev3_uart_build_nack(msg) == 1 && msg[0] == EV3_UART_SYS_NACK);

		CHECK(lost == (ev.type == EV3_UART_EV_ERROR));
		event(h, &ev, 0);
	}
	if (rnd(h) % 64 == 0) {
		ev3_uart_parser_line_error(p, &ev);
		event(h, &ev, 0);
	}
	if (rnd(h) % 32 == 0)
		probe(h);
}

/*
 * The differential check of batching: the same bytes go to one parser one
 * at a time, and to another in batches of 1 to 64 bytes (so messages whole
 * in a batch, and messages split anywhere between two). Both must give the
 * same events, at the same offsets in the stream, with the same payloads,
 * and be in the same state after every batch. The hosts answer a handshake
 * at once and, between batches, do the same SELECTs, keep-alive ticks and
 * line errors.
 */
/* Events of one batch: at most one a byte, the replayed bytes and two more. */
#define DIFF_MAX_EVENTS	(64 + EV3_UART_MAX_MSG_LEN + 2)

struct diff_run {
	size_t step;		/* bytes per call: 1, or 0 for the whole batch */
	struct ev3_uart_parser p;
	struct ev3_uart_event ev[DIFF_MAX_EVENTS];
	size_t at[DIFF_MAX_EVENTS];	/* stream offset after the event */
	u8 data[DIFF_MAX_EVENTS][EV3_UART_MAX_PAYLOAD];
	unsigned int n;
};

static void diff_event(struct diff_run *r, const struct ev3_uart_event *ev,
		       size_t at)
{
	if (ev->type == EV3_UART_EV_NONE)
		return;
	CHECK(r->n < DIFF_MAX_EVENTS);
	r->ev[r->n] = *ev;
	r->at[r->n] = at;
	if (ev->type == EV3_UART_EV_DATA)
		memcpy(r->data[r->n], r->p.data, ev->len);
	r->n++;
	if (ev->type == EV3_UART_EV_HANDSHAKE)
		ev3_uart_parser_start_data(&r->p);
}

/* Feed @len bytes at stream offset @at, as @r does. */
static void diff_feed(struct diff_run *r, const u8 *buf, size_t len, size_t at)
{
	struct ev3_uart_event ev;
	size_t n, used;

	do {
		n = r->step && len > r->step ? r->step : len;
		used = ev3_uart_parser_feed(&r->p, buf, n, &ev);
		CHECK(used <= n);
		CHECK(ev.type != EV3_UART_EV_NONE || used == n);
		buf += used;
		len -= used;
		at += used;
		diff_event(r, &ev, at);
	} while (len || ev.type != EV3_UART_EV_NONE);
}

/* What must agree: all but the scratch of a message already handled. */
static void diff_state(const struct ev3_uart_parser *a,
		       const struct ev3_uart_parser *b)
{
	CHECK(a->state == b->state);
	CHECK(a->sync_speed == b->sync_speed);
	CHECK(!memcmp(&a->sensor, &b->sensor, sizeof(a->sensor)));
	CHECK(a->msg_len == b->msg_len);
	CHECK(!memcmp(a->msg, b->msg, a->msg_len));
	CHECK(a->replay_len - a->replay_pos == b->replay_len - b->replay_pos);
	CHECK(!memcmp(a->replay + a->replay_pos, b->replay + b->replay_pos,
		      a->replay_len - a->replay_pos));
	CHECK(a->cmd_seen == b->cmd_seen);
	CHECK(a->info_mode == b->info_mode);
	CHECK(a->info_seen == b->info_seen);
	CHECK(a->modes_done == b->modes_done);
	CHECK(!memcmp(a->stash, b->stash, sizeof(a->stash)));
	CHECK(a->mode == b->mode);
	CHECK(a->ext_mode == b->ext_mode);
	CHECK(a->pending_mode == b->pending_mode);
	CHECK(a->data_err == b->data_err);
	CHECK(a->silent_ticks == b->silent_ticks);
	CHECK(a->data_since_tick == b->data_since_tick);
	CHECK(a->frames == b->frames);
	CHECK(a->bad_frames == b->bad_frames);
	CHECK(a->garbage == b->garbage);
}

static void diff_logs(const struct diff_run *a, const struct diff_run *b)
{
	unsigned int i;

	CHECK(a->n == b->n);
	for (i = 0; i < a->n; i++) {
		CHECK(a->ev[i].type == b->ev[i].type);
		CHECK(a->at[i] == b->at[i]);
		switch (a->ev[i].type) {
		case EV3_UART_EV_DATA:
			CHECK(a->ev[i].mode == b->ev[i].mode);
			CHECK(a->ev[i].mode_changed == b->ev[i].mode_changed);
			CHECK(a->ev[i].us_dc_in == b->ev[i].us_dc_in);
			CHECK(a->ev[i].len == b->ev[i].len);
			CHECK(!memcmp(a->data[i], b->data[i], a->ev[i].len));
			break;
		case EV3_UART_EV_ERROR:
			CHECK(!strcmp(a->ev[i].reason, b->ev[i].reason));
			break;
		default:
			break;
		}
	}
}

static void differential(const u8 *data, size_t size, u32 seed)
{
	/* Static: a few hundred kilobytes to clear for every input is slow. */
	static struct diff_run r[2];
	struct host h = { .rng = seed ? seed : 0x2545f491 };
	struct ev3_uart_event ev[2];
	size_t at = 0, n;
	unsigned int i;
	bool lost[2];
	int ret[2];
	u8 mode;

	r[0].step = 1;
	r[1].step = 0;
	for (i = 0; i < 2; i++)
		ev3_uart_parser_init(&r[i].p);
	while (at < size) {
		n = 1 + rnd(&h) % 64;
		n = n < size - at ? n : size - at;
		for (i = 0; i < 2; i++) {
			r[i].n = 0;
			diff_feed(&r[i], data + at, n, at);
		}
		at += n;
		if (rnd(&h) % 8 == 0) {
			mode = rnd(&h) % (EV3_UART_MAX_MODES + 1);
			for (i = 0; i < 2; i++)
				ret[i] = ev3_uart_parser_select(&r[i].p, mode);
			CHECK(ret[0] == ret[1]);
		}
		if (rnd(&h) % 4 == 0) {
			for (i = 0; i < 2; i++) {
				lost[i] = ev3_uart_parser_tick(&r[i].p, &ev[i]);
				diff_event(&r[i], &ev[i], at);
			}
			CHECK(lost[0] == lost[1]);
		}
		if (rnd(&h) % 32 == 0) {
			for (i = 0; i < 2; i++) {
				ev3_uart_parser_line_error(&r[i].p, &ev[i]);
				diff_event(&r[i], &ev[i], at);
			}
		}
		if (rnd(&h) % 32 == 0) {
			for (i = 0; i < 2; i++)
				ret[i] = ev3_uart_parser_probe(&r[i].p, EV3_UART_SPEED_FAST);
			CHECK(ret[0] == ret[1]);
		} else if (rnd(&h) % 4 == 0) {
			for (i = 0; i < 2; i++)
				ret[i] = ev3_uart_parser_probe_end(&r[i].p);
			CHECK(ret[0] == ret[1]);
		}
		diff_logs(&r[0], &r[1]);
		diff_state(&r[0].p, &r[1].p);
	}
}

static int verbose = -1;	/* FUZZ_VERBOSE set: a line per input */

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
	struct host h = { };
	struct ev3_uart_event ev;
	size_t n;

	/* On the heap, so that ASan sees any access past its end. */
	h.p = malloc(sizeof(*h.p));
	CHECK(h.p);
	if (size >= 4) {
		h.rng = data[0] | data[1] << 8 | data[2] << 16 | (u32)data[3] << 24;
		data += 4;
		size -= 4;
	}
	/*
	 * One input in four (by its host seed): the check makes an input
	 * about twice as slow, and make fuzz has an execution target.
	 */
	if (!(h.rng & 3))
		differential(data, size, h.rng);
	ev3_uart_parser_init(h.p);
	check_parser(h.p);

	while (size) {
		n = h.rng ? 1 + rnd(&h) % 64 : size;
		n = n < size ? n : size;
		receive(&h, data, n);
		data += n;
		size -= n;
		if (h.p->state == EV3_UART_STATE_ACKED && h.acked_wait &&
		    !--h.acked_wait)
			start_data(&h);
		if (h.probe_wait && !--h.probe_wait)
			probe_end(&h);
		if (h.rng)
			host_actions(&h);
	}
	if (h.p->state == EV3_UART_STATE_ACKED)
		start_data(&h);
	/* Bytes left in the replay buffer come out with the next batch. */
	for (n = 0; n <= EV3_UART_MAX_MSG_LEN; n++) {
		CHECK(ev3_uart_parser_feed(h.p, (const u8 *)"", 0, &ev) == 0);
		event(&h, &ev, 0);
		if (ev.type == EV3_UART_EV_NONE)
			break;
	}
	CHECK(ev.type == EV3_UART_EV_NONE);
	CHECK(h.p->replay_pos == h.p->replay_len);
	check_description(h.p);
	if (verbose < 0)
		verbose = !!getenv("FUZZ_VERBOSE");
	if (verbose)
		printf("type %u, state %u, %lu events, %lu frames, %lu bad, %lu garbage\n",
		       h.p->sensor.type, h.p->state, h.events, h.p->frames,
		       h.p->bad_frames, h.p->garbage);
	free(h.p);
	return 0;
}

#ifndef FUZZ_REPLAY
/*
 * Most mutations of a message break its checksum, and the parser then
 * stops at the checksum: after libFuzzer's own mutation, frame the stream
 * as the parser would and make the checksums right again (three times out
 * of four), so that the fuzzer gets past the checksums to what they guard.
 */
size_t LLVMFuzzerCustomMutator(u8 *data, size_t size, size_t max_size,
			       unsigned int seed)
{
	size_t i = 4, len;
	u8 b;

	size = LLVMFuzzerMutate(data, size, max_size);
	if (seed % 4 == 0)
		return size;
	while (i < size) {
		b = data[i];
		if (b == 0xff || (b & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_SYS) {
			i++;
			continue;
		}
		len = ev3_uart_msg_len(b);
		if (i + len > size)
			break;
		data[i + len - 1] = ev3_uart_checksum(data + i, len - 1);
		i += len;
	}
	return size;
}
#endif
