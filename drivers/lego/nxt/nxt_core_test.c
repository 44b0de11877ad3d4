// SPDX-License-Identifier: GPL-2.0
/*
 * KUnit tests for the NXT transaction engine, over a fake transport.
 *
 * The fake sends at once or never, answers with a packet given in advance
 * or not at all, and counts what the engine asks of it, so that each path
 * of a transaction (a reply, none, a wrong one, a telegram the brick does
 * not take, a stall, a lost link) is run without USB.
 */
#include <kunit/test.h>
#include <linux/delay.h>
#include <linux/err.h>
#include <linux/module.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "nxt_core.h"

/* Short reply timeout of the tests, in milliseconds. */
#define FAKE_TIMEOUT_MS	30

/**
 * struct fake_link - a transport that needs no hardware
 * @brick: the brick
 * @tg: the last telegram sent
 * @tg_len: its length
 * @sends: telegrams sent
 * @send_err: what send() fails with, or 0
 * @taken: the brick takes each telegram at once (else only unlink or kill
 *	end the send)
 * @reply: what the brick answers to the next telegram, if @reply_len
 * @reply_len: its length; 0 for no answer
 * @x: the transaction whose send runs, for unlink() and kill()
 * @refs: references to the send's handle held by the engine
 * @opens: open() calls
 * @closes: close() calls
 * @starts: start() calls
 * @unlinks: unlink() calls
 * @released: release() was called
 */
struct fake_link {
	struct nxt_brick brick;
	u8 tg[NXT_TELEGRAM_MAX];
	unsigned int tg_len;
	unsigned int sends;
	int send_err;
	bool taken;
	u8 reply[NXT_TELEGRAM_MAX];
	unsigned int reply_len;
	struct nxt_xfer *x;
	int refs;
	unsigned int opens;
	unsigned int closes;
	unsigned int starts;
	unsigned int unlinks;
	bool released;
};

static struct fake_link *to_fake(struct nxt_brick *b)
{
	return container_of(b, struct fake_link, brick);
}

static int fake_open(struct nxt_brick *b)
{
	to_fake(b)->opens++;
	return 0;
}

static void fake_close(struct nxt_brick *b)
{
	to_fake(b)->closes++;
}

static int fake_start(struct nxt_brick *b)
{
	to_fake(b)->starts++;
	return 0;
}

/* A packet from the fake brick, as a receive completion gives it. */
static void fake_rx(struct fake_link *f, const u8 *buf, unsigned int len)
{
	spin_lock_irq(&f->brick.lock);
	nxt_brick_rx(&f->brick, buf, len);
	spin_unlock_irq(&f->brick.lock);
}

static void *fake_send(struct nxt_brick *b, struct nxt_xfer *x)
{
	struct fake_link *f = to_fake(b);

	if (f->send_err)
		return ERR_PTR(f->send_err);
	memcpy(f->tg, x->tg, x->len);
	f->tg_len = x->len;
	f->sends++;
	f->refs++;
	f->x = x;
	if (f->taken) {
		f->x = NULL;
		nxt_brick_sent(b, x, 0);
		if (f->reply_len)
			fake_rx(f, f->reply, f->reply_len);
	}
	return f;
}

static void fake_unlink(void *handle)
{
	struct fake_link *f = handle;
	struct nxt_xfer *x = f->x;

	f->unlinks++;
	f->x = NULL;
	if (x)
		nxt_brick_sent(&f->brick, x, -EINTR);
}

static void fake_get(void *handle)
{
	((struct fake_link *)handle)->refs++;
}

static void fake_put(void *handle)
{
	((struct fake_link *)handle)->refs--;
}

static void fake_release(struct nxt_brick *b)
{
	to_fake(b)->released = true;
}

static const struct nxt_transport_ops fake_ops = {
	.open		= fake_open,
	.close		= fake_close,
	.start		= fake_start,
	.send		= fake_send,
	.unlink		= fake_unlink,
	.kill		= fake_unlink,
	.get		= fake_get,
	.put		= fake_put,
	.release	= fake_release,
	.owner		= THIS_MODULE,
};

/* The suite's exit: the brick of the test goes, as a transport's would. */
static void nxt_core_test_exit(struct kunit *test)
{
	struct fake_link *f = test->priv;

	if (!f)
		return;
	mutex_lock(&f->brick.tx_lock);
	nxt_brick_disconnect(&f->brick);
	mutex_unlock(&f->brick.tx_lock);
	nxt_brick_shutdown(&f->brick);
	nxt_brick_put(&f->brick);
}

/* A brick on a fake link that takes every telegram, with no reply set. */
static struct fake_link *fake_new(struct kunit *test)
{
	struct fake_link *f = kunit_kzalloc(test, sizeof(*f), GFP_KERNEL);

	KUNIT_ASSERT_NOT_NULL(test, f);
	nxt_brick_init(&f->brick, &fake_ops, NULL, "fake");
	f->taken = true;
	test->priv = f;
	return f;
}

static void fake_answer(struct fake_link *f, const u8 *reply, unsigned int len)
{
	memcpy(f->reply, reply, len);
	f->reply_len = len;
}

static struct nxt_stats fake_stats(struct fake_link *f)
{
	struct nxt_stats st;

	spin_lock_irq(&f->brick.lock);
	st = f->brick.stats;
	spin_unlock_irq(&f->brick.lock);
	return st;
}

/* GetBatteryLevel and its reply: 8000 mV. */
static const u8 battery[] = { 0x00, 0x0b };
static const u8 battery_reply[] = { 0x02, 0x0b, 0x00, 0x40, 0x1f };

/* A reply goes to its transaction, and what it says about the brick is kept. */
static void nxt_core_test_reply(struct kunit *test)
{
	struct fake_link *f = fake_new(test);
	struct nxt_brick_info info;
	struct nxt_stats st;
	struct nxt_xfer x;

	fake_answer(f, battery_reply, sizeof(battery_reply));
	KUNIT_ASSERT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), 0);
	KUNIT_EXPECT_EQ(test, x.reply_len, sizeof(battery_reply));
	KUNIT_EXPECT_MEMEQ(test, x.reply, battery_reply, sizeof(battery_reply));
	KUNIT_EXPECT_EQ(test, f->sends, 1U);
	KUNIT_EXPECT_MEMEQ(test, f->tg, battery, sizeof(battery));
	KUNIT_EXPECT_EQ(test, f->starts, 1U);
	KUNIT_EXPECT_EQ(test, f->refs, 0);
	st = fake_stats(f);
	KUNIT_EXPECT_EQ(test, st.telegrams, 1ULL);
	KUNIT_EXPECT_EQ(test, st.replies, 1ULL);
	KUNIT_EXPECT_EQ(test, st.ok, 1ULL);
	nxt_brick_info(&f->brick, &info);
	KUNIT_EXPECT_TRUE(test, info.have_battery);
	KUNIT_EXPECT_EQ(test, info.battery_mv, 8000);
	KUNIT_EXPECT_TRUE(test, nxt_slot_free(&f->brick));
}

/* A telegram that asks for no reply is done once the brick has it. */
static void nxt_core_test_no_reply(struct kunit *test)
{
	static const u8 noreply[] = { 0x80, 0x0b };
	struct fake_link *f = fake_new(test);
	struct nxt_xfer x;

	KUNIT_ASSERT_EQ(test, nxt_transact(&f->brick, &x, noreply, sizeof(noreply),
					   FAKE_TIMEOUT_MS, false), 0);
	KUNIT_EXPECT_EQ(test, x.reply_len, 0U);
	KUNIT_EXPECT_FALSE(test, x.want_reply);
	KUNIT_EXPECT_EQ(test, fake_stats(f).ok, 1ULL);
}

/* Nothing reaches the transport of a telegram the engine refuses. */
static void nxt_core_test_bad_telegram(struct kunit *test)
{
	static const u8 reply_type[] = { 0x02, 0x0b };
	static const u8 short_output[] = { 0x00, 0x04, 0x00 };	/* SetOutputState */
	u8 long_tg[NXT_TELEGRAM_MAX + 1] = { 0x00, 0x0b };
	struct fake_link *f = fake_new(test);
	struct nxt_xfer x;

	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, reply_type, 2, FAKE_TIMEOUT_MS,
					   false), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, short_output, 3, FAKE_TIMEOUT_MS,
					   false), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, long_tg, sizeof(long_tg),
					   FAKE_TIMEOUT_MS, false), -EMSGSIZE);
	KUNIT_EXPECT_EQ(test, f->sends, 0U);
	KUNIT_EXPECT_EQ(test, fake_stats(f).transactions, 0ULL);
}

/*
 * No reply: -ETIMEDOUT after the timeout; the late reply is then drained,
 * and ends the drain when it comes, so that it never answers the next
 * telegram.
 */
static void nxt_core_test_timeout_and_late_reply(struct kunit *test)
{
	struct fake_link *f = fake_new(test);
	struct nxt_stats st;
	struct nxt_xfer x;

	KUNIT_ASSERT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), -ETIMEDOUT);
	KUNIT_EXPECT_FALSE(test, nxt_slot_free(&f->brick));
	fake_rx(f, battery_reply, sizeof(battery_reply));
	KUNIT_EXPECT_TRUE(test, nxt_slot_free(&f->brick));
	st = fake_stats(f);
	KUNIT_EXPECT_EQ(test, st.err_timedout, 1ULL);
	KUNIT_EXPECT_EQ(test, st.drained, 1ULL);
	KUNIT_EXPECT_EQ(test, st.replies, 0ULL);

	/* The next telegram gets its own reply. */
	fake_answer(f, battery_reply, sizeof(battery_reply));
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), 0);
	KUNIT_EXPECT_EQ(test, fake_stats(f).replies, 1ULL);
}

/* Only packets that are not the reply came: -EPROTO, not -ETIMEDOUT. */
static void nxt_core_test_wrong_reply(struct kunit *test)
{
	static const u8 other[] = { 0x02, 0x0c, 0x00 };
	static const u8 short_battery[] = { 0x02, 0x0b, 0x00, 0x40 };
	struct fake_link *f = fake_new(test);
	struct nxt_xfer x;

	fake_answer(f, other, sizeof(other));
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), -EPROTO);
	fake_answer(f, short_battery, sizeof(short_battery));
	msleep(NXT_DRAIN_MS * 2);
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), -EPROTO);
	KUNIT_EXPECT_EQ(test, fake_stats(f).mismatched, 2ULL);
	KUNIT_EXPECT_EQ(test, fake_stats(f).err_proto, 2ULL);
}

/*
 * The brick does not take the telegram: at the deadline the engine asks
 * the transport to stop the send, and the transaction times out.
 */
static void nxt_core_test_not_taken(struct kunit *test)
{
	struct fake_link *f = fake_new(test);
	struct nxt_xfer x;

	f->taken = false;
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), -ETIMEDOUT);
	KUNIT_EXPECT_EQ(test, f->unlinks, 1U);
	KUNIT_EXPECT_FALSE(test, x.delivered);
	KUNIT_EXPECT_EQ(test, f->refs, 0);
	/* Not taken: a short drain only, with no reply to wait for. */
	KUNIT_EXPECT_FALSE(test, f->brick.orphan);
}

/* Errors of the link end the transaction with the transport's errno. */
static void nxt_core_test_link_errors(struct kunit *test)
{
	struct fake_link *f = fake_new(test);
	struct nxt_xfer x;

	f->send_err = -EIO;
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), -EIO);
	KUNIT_EXPECT_EQ(test, fake_stats(f).err_io, 1ULL);
	f->send_err = 0;

	/* A stall while the reply is awaited: -EPIPE. */
	KUNIT_ASSERT_EQ(test, nxt_xfer_start(&f->brick, &x, battery, sizeof(battery),
					     FAKE_TIMEOUT_MS, false), 0);
	spin_lock_irq(&f->brick.lock);
	nxt_brick_in_stalled(&f->brick);
	spin_unlock_irq(&f->brick.lock);
	KUNIT_EXPECT_EQ(test, nxt_xfer_wait(&f->brick, &x, false), -EPIPE);

	/* Paused (a reset under way): nothing is sent. */
	msleep(NXT_DRAIN_MS * 2);
	mutex_lock(&f->brick.tx_lock);
	f->brick.paused = true;
	mutex_unlock(&f->brick.tx_lock);
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), -EIO);
	KUNIT_EXPECT_EQ(test, f->sends, 1U);
}

/* A receive error may be an unplug: the deadline is extended once, then -EIO. */
static void nxt_core_test_unplug_grace(struct kunit *test)
{
	struct fake_link *f = fake_new(test);
	unsigned long start = jiffies;
	struct nxt_xfer x;

	KUNIT_ASSERT_EQ(test, nxt_xfer_start(&f->brick, &x, battery, sizeof(battery),
					     FAKE_TIMEOUT_MS, false), 0);
	spin_lock_irq(&f->brick.lock);
	nxt_brick_link_error(&f->brick);
	spin_unlock_irq(&f->brick.lock);
	KUNIT_EXPECT_EQ(test, nxt_xfer_wait(&f->brick, &x, false), -EIO);
	KUNIT_EXPECT_GE(test, jiffies_to_msecs(jiffies - start), NXT_UNPLUG_GRACE_MS);
}

/* The link goes: the transaction waiting for its reply and later ones get -ENODEV. */
static void nxt_core_test_disconnect(struct kunit *test)
{
	struct fake_link *f = fake_new(test);
	struct nxt_xfer x;

	KUNIT_ASSERT_EQ(test, nxt_xfer_start(&f->brick, &x, battery, sizeof(battery),
					     10000, false), 0);
	KUNIT_EXPECT_FALSE(test, nxt_xfer_done(&f->brick, &x));
	mutex_lock(&f->brick.tx_lock);
	nxt_brick_disconnect(&f->brick);
	mutex_unlock(&f->brick.tx_lock);
	KUNIT_EXPECT_EQ(test, nxt_xfer_wait(&f->brick, &x, true), -ENODEV);
	KUNIT_EXPECT_TRUE(test, nxt_gone(&f->brick));
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &x, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, false), -ENODEV);
	KUNIT_EXPECT_EQ(test, fake_stats(f).err_nodev, 1ULL);
}

/*
 * The slot: a second transaction waits while the first holds it, and with
 * O_NONBLOCK fails with -EAGAIN without sending.
 */
static void nxt_core_test_busy(struct kunit *test)
{
	struct fake_link *f = fake_new(test);
	struct nxt_xfer x, y;

	KUNIT_ASSERT_EQ(test, nxt_xfer_start(&f->brick, &x, battery, sizeof(battery),
					     10000, false), 0);
	KUNIT_EXPECT_FALSE(test, nxt_slot_free(&f->brick));
	KUNIT_EXPECT_EQ(test, nxt_transact(&f->brick, &y, battery, sizeof(battery),
					   FAKE_TIMEOUT_MS, true), -EAGAIN);
	KUNIT_EXPECT_EQ(test, f->sends, 1U);
	fake_rx(f, battery_reply, sizeof(battery_reply));
	KUNIT_EXPECT_EQ(test, nxt_xfer_wait(&f->brick, &x, true), 0);
	/* A cancelled transaction frees the slot; its late reply is drained. */
	KUNIT_ASSERT_EQ(test, nxt_xfer_start(&f->brick, &y, battery, sizeof(battery),
					     10000, false), 0);
	nxt_xfer_cancel(&f->brick, &y);
	KUNIT_EXPECT_EQ(test, nxt_xfer_wait(&f->brick, &y, true), -EINTR);
	fake_rx(f, battery_reply, sizeof(battery_reply));
	KUNIT_EXPECT_EQ(test, fake_stats(f).drained, 1ULL);
	KUNIT_EXPECT_TRUE(test, nxt_slot_free(&f->brick));
}

/* The transport hears of the first open and of the last close only. */
static void nxt_core_test_opens(struct kunit *test)
{
	struct fake_link *f = fake_new(test);

	KUNIT_EXPECT_EQ(test, nxt_brick_open(&f->brick), 0);
	KUNIT_EXPECT_EQ(test, nxt_brick_open(&f->brick), 0);
	KUNIT_EXPECT_EQ(test, f->opens, 1U);
	nxt_brick_close(&f->brick);
	KUNIT_EXPECT_EQ(test, f->closes, 0U);
	nxt_brick_close(&f->brick);
	KUNIT_EXPECT_EQ(test, f->closes, 1U);
	KUNIT_EXPECT_EQ(test, nxt_brick_open(&f->brick), 0);
	KUNIT_EXPECT_EQ(test, f->opens, 2U);
	nxt_brick_close(&f->brick);
}

static struct kunit_case nxt_core_cases[] = {
	KUNIT_CASE(nxt_core_test_reply),
	KUNIT_CASE(nxt_core_test_no_reply),
	KUNIT_CASE(nxt_core_test_bad_telegram),
	KUNIT_CASE(nxt_core_test_timeout_and_late_reply),
	KUNIT_CASE(nxt_core_test_wrong_reply),
	KUNIT_CASE(nxt_core_test_not_taken),
	KUNIT_CASE(nxt_core_test_link_errors),
	KUNIT_CASE(nxt_core_test_unplug_grace),
	KUNIT_CASE(nxt_core_test_disconnect),
	KUNIT_CASE(nxt_core_test_busy),
	KUNIT_CASE(nxt_core_test_opens),
	{}
};

static struct kunit_suite nxt_core_suite = {
	.name = "lego_nxt_core",
	.exit = nxt_core_test_exit,
	.test_cases = nxt_core_cases,
};

kunit_test_suite(nxt_core_suite);
