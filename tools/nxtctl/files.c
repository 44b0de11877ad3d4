// SPDX-License-Identifier: GPL-2.0
/*
 * nxtctl: the brick's flash file system through system commands sent with
 * NXT_IOC_TRANSACT (OpenRead/OpenWrite/Read/Write/Close/Delete and
 * FindFirst/FindNext), built and decoded by liblegonxt. Every telegram and
 * reply fits one 64-byte packet: a Write carries at most 61 data bytes
 * (LNXT_WRITE_MAX), a Read asks for at most 58 (LNXT_READ_MAX: the
 * firmware caps its USB reply there but echoes the count asked for).
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "nxtctl.h"

#define LOCAL_MAX	(16 * 1024 * 1024)	/* far more than the flash holds */

/*
 * A progress bar on standard error, only when it is a terminal:
 * "download Demo.rxe [#########.........]  33%  85/256 bytes".
 */
#define BAR_WIDTH	30

static int show_progress = -1;

static void progress(const char *what, const char *name, size_t done, size_t total)
{
	char bar[BAR_WIDTH + 1];
	size_t fill, pct;

	if (show_progress < 0)
		show_progress = isatty(STDERR_FILENO);
	if (!show_progress)
		return;
	pct = total ? done * 100 / total : 100;
	fill = total ? done * BAR_WIDTH / total : BAR_WIDTH;
	memset(bar, '#', fill);
	memset(bar + fill, '.', BAR_WIDTH - fill);
	bar[BAR_WIDTH] = 0;
	fprintf(stderr, "\r%s %s [%s] %3zu%%  %zu/%zu bytes", what, name, bar, pct,
		done, total);
}

/* End the bar's line, after success or before an error message. */
void progress_end(void)
{
	if (show_progress > 0)
		fputc('\n', stderr);
	show_progress = -1;
}

/* Close a handle after an error: best effort, the first error is reported. */
static void close_quietly(__u8 handle)
{
	struct nxt_transaction t;
	struct lnxt_msg m;

	lnxt_close(&m, handle);
	load_telegram(&t, &m);
	(void)ioctl(nxt_fd, NXT_IOC_TRANSACT, &t);
}

static int close_handle(__u8 handle, const char *what)
{
	struct nxt_transaction t;
	struct lnxt_msg m;

	lnxt_close(&m, handle);
	return command(&m, &t, what);
}

/* Delete @name (checked): the brick's status in @status. */
static int delete_file(const char *name, int *status)
{
	struct nxt_transaction t;
	struct lnxt_msg m;

	if (lnxt_delete(&m, name))
		return EXIT_USAGE;
	return exchange(&m, &t, status, "Delete");
}

static int read_local(const char *path, __u8 **data, size_t *size)
{
	size_t cap = 4096, len = 0;
	ssize_t n;
	__u8 *buf;
	int fd;

	fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0) {
		fprintf(stderr, "nxtctl: cannot open %s: %s\n", path, strerror(errno));
		return EXIT_DEVICE;
	}
	buf = malloc(cap);
	for (;;) {
		if (!buf) {
			fprintf(stderr, "nxtctl: %s: out of memory\n", path);
			close(fd);
			return EXIT_DEVICE;
		}
		n = read(fd, buf + len, cap - len);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0) {
			fprintf(stderr, "nxtctl: cannot read %s: %s\n", path, strerror(errno));
			free(buf);
			close(fd);
			return EXIT_DEVICE;
		}
		if (n == 0)
			break;
		len += n;
		if (len > LOCAL_MAX) {
			fprintf(stderr, "nxtctl: %s: too big for the brick\n", path);
			free(buf);
			close(fd);
			return EXIT_DEVICE;
		}
		if (len == cap) {
			__u8 *bigger;

			cap *= 2;
			bigger = realloc(buf, cap);
			if (!bigger)
				free(buf);
			buf = bigger;
		}
	}
	close(fd);
	*data = buf;
	*size = len;
	return EXIT_OK;
}

static int open_write(const char *remote, size_t size, int *status, __u8 *handle)
{
	struct nxt_transaction t;
	struct lnxt_msg m;
	int ret;

	if (lnxt_open_write(&m, remote, size))
		return EXIT_USAGE;
	ret = exchange(&m, &t, status, "OpenWrite");
	if (ret || *status)
		return ret;
	if (lnxt_parse_handle(t.reply, t.reply_length, handle))
		return bad_reply("OpenWrite");
	return EXIT_OK;
}

int cmd_upload(int argc, char **argv)
{
	struct opt opts[] = { { .name = "force" }, {} };
	__u8 handle, echoed, *data = NULL;
	struct nxt_transaction t;
	struct lnxt_msg m;
	size_t size, off, n;
	__u16 written;
	int status;
	const char *remote;
	char *pos[2];
	int npos, ret;

	ret = parse_opts("upload", argc, argv, opts, pos, &npos, 1, 2);
	if (ret)
		return ret;
	remote = npos > 1 ? pos[1] : strrchr(pos[0], '/') ? strrchr(pos[0], '/') + 1 : pos[0];
	ret = check_name("upload", remote);
	if (ret)
		return ret;
	ret = read_local(pos[0], &data, &size);
	if (ret)
		return ret;

	ret = open_write(remote, size, &status, &handle);
	if (ret)
		goto out;
	if (status == LNXT_STATUS_FILE_EXISTS && opts[0].set) {
		ret = delete_file(remote, &status);
		if (ret)
			goto out;
		if (status) {
			ret = brick_error("Delete (--force)", status);
			goto out;
		}
		ret = open_write(remote, size, &status, &handle);
		if (ret)
			goto out;
	}
	if (status == LNXT_STATUS_FILE_EXISTS) {
		ret = brick_error("OpenWrite", status);
		fprintf(stderr, "nxtctl: %s is on the brick already; use --force to replace it\n",
			remote);
		goto out;
	}
	if (status) {
		ret = brick_error("OpenWrite", status);
		goto out;
	}

	progress("upload", remote, 0, size);
	for (off = 0; off < size; off += n) {
		n = size - off;
		if (n > LNXT_WRITE_MAX)
			n = LNXT_WRITE_MAX;
		lnxt_write(&m, handle, data + off, n);
		ret = command(&m, &t, "Write");
		if (ret)
			goto fail;
		if (lnxt_parse_write(t.reply, t.reply_length, &echoed, &written)) {
			ret = bad_reply("Write");
			goto fail;
		}
		progress("upload", remote, off + n, size);
		if (written != n) {
			progress_end();
			fprintf(stderr, "nxtctl: Write: the brick took %u of %zu bytes\n",
				written, n);
			ret = EXIT_DEVICE;
			goto fail;
		}
	}
	progress_end();
	ret = close_handle(handle, "Close");
	if (ret)
		goto out;
	free(data);
	return EXIT_OK;

fail:
	/* Do not leave a half-written file behind. */
	close_quietly(handle);
	delete_file(remote, &status);
out:
	free(data);
	return ret;
}

static int write_all(int fd, const __u8 *buf, size_t len)
{
	ssize_t n;

	while (len) {
		n = write(fd, buf, len);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0)
			return -1;
		buf += n;
		len -= n;
	}
	return 0;
}

/*
 * The temporary file a download goes to, next to @local so that rename()
 * replaces @local at once: ".NAME.XXXXXX" in the same directory, with the
 * mode an existing @local has, or 0666 less the umask.
 */
static int open_temp(const char *local, char **tmp)
{
	const char *base = strrchr(local, '/');
	size_t dirlen = base ? (size_t)(base - local) + 1 : 0;
	struct stat st;
	mode_t mode, mask;
	int fd;

	base = base ? base + 1 : local;
	*tmp = malloc(dirlen + strlen(base) + 9);
	if (!*tmp) {
		errno = ENOMEM;
		return -1;
	}
	sprintf(*tmp, "%.*s.%s.XXXXXX", (int)dirlen, local, base);
	fd = mkstemp(*tmp);
	if (fd < 0) {
		free(*tmp);
		*tmp = NULL;
		return -1;
	}
	if (stat(local, &st) == 0 && S_ISREG(st.st_mode)) {
		mode = st.st_mode & 07777;
	} else {
		mask = umask(0);
		umask(mask);
		mode = 0666 & ~mask;
	}
	/* Not fatal if it fails: the file stays 0600. */
	(void)fchmod(fd, mode);
	return fd;
}

int cmd_download(int argc, char **argv)
{
	struct nxt_transaction t;
	struct lnxt_file f;
	struct lnxt_data d;
	struct lnxt_msg m;
	const char *local;
	char *tmp = NULL;
	__u32 size, off, n;
	int npos, ret, fd;
	char *pos[2];
	__u8 handle;

	ret = parse_opts("download", argc, argv, NULL, pos, &npos, 1, 2);
	if (ret)
		return ret;
	ret = check_name("download", pos[0]);
	if (ret)
		return ret;
	local = npos > 1 ? pos[1] : pos[0];

	if (lnxt_open_read(&m, pos[0]))
		return EXIT_USAGE;
	ret = command(&m, &t, "OpenRead");
	if (ret)
		return ret;
	if (lnxt_parse_file(t.reply, t.reply_length, &f))
		return bad_reply("OpenRead");
	handle = f.handle;
	size = f.size;

	/* A failed download leaves an existing LOCAL as it was. */
	if (!strcmp(local, "-"))
		fd = STDOUT_FILENO;
	else
		fd = open_temp(local, &tmp);
	if (fd < 0) {
		fprintf(stderr, "nxtctl: cannot create %s: %s\n", local, strerror(errno));
		close_quietly(handle);
		return EXIT_DEVICE;
	}

	progress("download", pos[0], 0, size);
	for (off = 0; off < size; off += n) {
		n = size - off;
		if (n > LNXT_READ_MAX)
			n = LNXT_READ_MAX;
		lnxt_read(&m, handle, n);
		ret = command(&m, &t, "Read");
		if (ret)
			goto fail;
		/* command() checked the length: as many bytes as asked for. */
		if (lnxt_parse_read(t.reply, t.reply_length, &d) || d.len != n) {
			ret = bad_reply("Read");
			goto fail;
		}
		if (write_all(fd, d.data, n)) {
			progress_end();
			fprintf(stderr, "nxtctl: cannot write %s: %s\n", local, strerror(errno));
			ret = EXIT_DEVICE;
			goto fail;
		}
		progress("download", pos[0], off + n, size);
	}
	progress_end();
	ret = close_handle(handle, "Close");
	if (fd == STDOUT_FILENO)
		return ret;
	if (ret) {
		close(fd);
		goto remove;
	}
	if (fsync(fd) || close(fd)) {
		fprintf(stderr, "nxtctl: cannot write %s: %s\n", local, strerror(errno));
		ret = EXIT_DEVICE;
		goto remove;
	}
	if (rename(tmp, local)) {
		fprintf(stderr, "nxtctl: cannot create %s: %s\n", local, strerror(errno));
		ret = EXIT_DEVICE;
		goto remove;
	}
	free(tmp);
	return EXIT_OK;

fail:
	close_quietly(handle);
	if (fd == STDOUT_FILENO)
		return ret;
	close(fd);
remove:
	unlink(tmp);
	free(tmp);
	return ret;
}

int cmd_ls(int argc, char **argv)
{
	struct nxt_transaction t;
	const char *pattern;
	struct lnxt_file f;
	struct lnxt_msg m;
	int npos, ret, status;
	__u8 handle;
	char *pos[1];

	ret = parse_opts("ls", argc, argv, NULL, pos, &npos, 0, 1);
	if (ret)
		return ret;
	pattern = npos ? pos[0] : "*.*";
	ret = check_name("ls", pattern);
	if (ret)
		return ret;
	if (lnxt_find_first(&m, pattern))
		return EXIT_USAGE;
	ret = exchange(&m, &t, &status, "FindFirst");
	if (ret)
		return ret;
	if (status == LNXT_STATUS_FILE_NOT_FOUND)
		return EXIT_OK;		/* nothing matches */
	if (status)
		return brick_error("FindFirst", status);
	if (lnxt_parse_file(t.reply, t.reply_length, &f))
		return bad_reply("FindFirst");
	handle = f.handle;
	for (;;) {
		printf("%8u  %s\n", f.size, f.name);
		lnxt_find_next(&m, handle);
		ret = exchange(&m, &t, &status, "FindNext");
		if (ret || status == LNXT_STATUS_FILE_NOT_FOUND)
			break;
		if (status) {
			ret = brick_error("FindNext", status);
			break;
		}
		if (lnxt_parse_file(t.reply, t.reply_length, &f)) {
			ret = bad_reply("FindNext");
			break;
		}
	}
	/* The search's handle may be closed already: ignore the answer. */
	close_quietly(handle);
	return ret;
}

int cmd_rm(int argc, char **argv)
{
	char *pos[16], what[40];
	int npos, ret, i, status;

	ret = parse_opts("rm", argc, argv, NULL, pos, &npos, 1, 16);
	if (ret)
		return ret;
	for (i = 0; i < npos; i++) {
		ret = check_name("rm", pos[i]);
		if (ret)
			return ret;
	}
	for (i = 0; i < npos; i++) {
		ret = delete_file(pos[i], &status);
		if (ret)
			return ret;
		if (status) {
			snprintf(what, sizeof(what), "Delete %s", pos[i]);
			return brick_error(what, status);
		}
	}
	return EXIT_OK;
}
