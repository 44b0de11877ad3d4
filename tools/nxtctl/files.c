// SPDX-License-Identifier: GPL-2.0
/*
 * nxtctl: the brick's flash file system through system commands sent with
 * NXT_IOC_TRANSACT (OpenRead/OpenWrite/Read/Write/Close/Delete and
 * FindFirst/FindNext). Every telegram and reply fits one 64-byte packet:
 * a Write carries at most 61 data bytes, a Read asks for at most 58 (the
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

/* A name as the 20-byte NUL-padded field of the system commands. */
static void name_field(__u8 *field, const char *name)
{
	memset(field, 0, NXT_NAME_LEN);
	memcpy(field, name, strnlen(name, NXT_NAME_LEN - 1));
}

/* Close a handle after an error: best effort, the first error is reported. */
static void close_quietly(__u8 handle)
{
	struct nxt_transaction t = {};

	t.telegram[0] = NXT_SYSTEM_CMD;
	t.telegram[1] = NXT_SYS_CLOSE;
	t.telegram[2] = handle;
	t.length = 3;
	(void)ioctl(nxt_fd, NXT_IOC_TRANSACT, &t);
}

static int close_handle(__u8 handle, const char *what)
{
	struct nxt_transaction t;
	int ret;

	ret = system_cmd(&t, NXT_SYS_CLOSE, &handle, 1, what);
	if (ret)
		return ret;
	if (t.reply[2])
		return brick_error(what, t.reply[2]);
	return EXIT_OK;
}

static int delete_file(const char *name, __u8 *status)
{
	struct nxt_transaction t;
	__u8 field[NXT_NAME_LEN];
	int ret;

	name_field(field, name);
	ret = system_cmd(&t, NXT_SYS_DELETE, field, sizeof(field), "Delete");
	if (ret)
		return ret;
	*status = t.reply[2];
	return EXIT_OK;
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

static int open_write(const char *remote, size_t size, __u8 *status, __u8 *handle)
{
	__u8 args[NXT_NAME_LEN + 4];
	struct nxt_transaction t;
	int ret;

	name_field(args, remote);
	put_le32(args + NXT_NAME_LEN, size);
	ret = system_cmd(&t, NXT_SYS_OPEN_WRITE, args, sizeof(args), "OpenWrite");
	if (ret)
		return ret;
	*status = t.reply[2];
	*handle = t.reply[3];
	return EXIT_OK;
}

int cmd_upload(int argc, char **argv)
{
	struct opt opts[] = { { .name = "force" }, {} };
	__u8 status, handle, *data = NULL;
	struct nxt_transaction t;
	size_t size, off, n;
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
	if (status == NXT_STATUS_FILE_EXISTS && opts[0].set) {
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
	if (status == NXT_STATUS_FILE_EXISTS) {
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
		if (n > NXT_WRITE_CHUNK)
			n = NXT_WRITE_CHUNK;
		memset(&t, 0, sizeof(t));
		t.telegram[0] = NXT_SYSTEM_CMD;
		t.telegram[1] = NXT_SYS_WRITE;
		t.telegram[2] = handle;
		memcpy(t.telegram + 3, data + off, n);
		t.length = 3 + n;
		ret = transact(&t, "Write");
		if (ret)
			goto fail;
		if (t.reply[2]) {
			ret = brick_error("Write", t.reply[2]);
			goto fail;
		}
		progress("upload", remote, off + n, size);
		if ((size_t)get_le16(t.reply + 4) != n) {
			progress_end();
			fprintf(stderr, "nxtctl: Write: the brick took %u of %zu bytes\n",
				get_le16(t.reply + 4), n);
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
	__u8 field[NXT_NAME_LEN], handle;
	const char *local;
	char *tmp = NULL;
	__u32 size, off, n;
	int npos, ret, fd;
	char *pos[2];

	ret = parse_opts("download", argc, argv, NULL, pos, &npos, 1, 2);
	if (ret)
		return ret;
	ret = check_name("download", pos[0]);
	if (ret)
		return ret;
	local = npos > 1 ? pos[1] : pos[0];

	name_field(field, pos[0]);
	ret = system_cmd(&t, NXT_SYS_OPEN_READ, field, sizeof(field), "OpenRead");
	if (ret)
		return ret;
	if (t.reply[2])
		return brick_error("OpenRead", t.reply[2]);
	handle = t.reply[3];
	size = get_le32(t.reply + 4);

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
		if (n > NXT_READ_CHUNK)
			n = NXT_READ_CHUNK;
		memset(&t, 0, sizeof(t));
		t.telegram[0] = NXT_SYSTEM_CMD;
		t.telegram[1] = NXT_SYS_READ;
		t.telegram[2] = handle;
		put_le16(t.telegram + 3, n);
		t.length = 5;
		ret = transact(&t, "Read");
		if (ret)
			goto fail;
		if (t.reply[2]) {
			ret = brick_error("Read", t.reply[2]);
			goto fail;
		}
		if (t.reply_length < 6 + n) {
			progress_end();
			fprintf(stderr, "nxtctl: Read: short reply (%u bytes for %u data bytes)\n",
				t.reply_length, n);
			ret = EXIT_DEVICE;
			goto fail;
		}
		if (write_all(fd, t.reply + 6, n)) {
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
	__u8 field[NXT_NAME_LEN], handle;
	const char *pattern;
	char name[NXT_NAME_LEN];
	int npos, ret;
	char *pos[1];

	ret = parse_opts("ls", argc, argv, NULL, pos, &npos, 0, 1);
	if (ret)
		return ret;
	pattern = npos ? pos[0] : "*.*";
	ret = check_name("ls", pattern);
	if (ret)
		return ret;
	name_field(field, pattern);
	ret = system_cmd(&t, NXT_SYS_FIND_FIRST, field, sizeof(field), "FindFirst");
	if (ret)
		return ret;
	if (t.reply[2] == NXT_STATUS_FILE_NOT_FOUND)
		return EXIT_OK;		/* nothing matches */
	if (t.reply[2])
		return brick_error("FindFirst", t.reply[2]);
	handle = t.reply[3];
	for (;;) {
		memcpy(name, t.reply + 4, NXT_NAME_LEN);
		name[NXT_NAME_LEN - 1] = 0;
		printf("%8u  %s\n", get_le32(t.reply + 24), name);
		ret = system_cmd(&t, NXT_SYS_FIND_NEXT, &handle, 1, "FindNext");
		if (ret)
			break;
		if (t.reply[2] == NXT_STATUS_FILE_NOT_FOUND)
			break;
		if (t.reply[2]) {
			ret = brick_error("FindNext", t.reply[2]);
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
	int npos, ret, i;
	__u8 status;

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
