# shellcheck shell=bash
# Shared by tools/upstream/series.sh and tests/upstream/check.sh. Source it
# with "top" (the checkout) and "series" (newest, 6.12, 6.1, ...) set; "prog"
# names the caller. "newest" becomes the series it is (7.3 today): the
# source is Debian's linux-source-SERIES, as tests/kernel/fetch-source.sh
# finds it (installed, or fetched into the kernel cache).

up_out=${LEGO_UPSTREAM_OUT:-$top/.build/upstream}
read -r series up_version up_tarball < <("$top/tests/kernel/fetch-source.sh" "$series") ||
	{ echo "$prog: no source for linux-source-$series" >&2; exit 1; }
# The scratch repository: the kernel source as one base commit, tagged by the
# Debian package's version, and the series on the branch lego-$series.
up_repo=$up_out/linux-$series
up_branch=lego-$series
up_patches=$up_out/$series

up_pkgver() {
	echo "$up_version"
}

# A git tag for the package version (no ~ or : in tags).
up_base_tag() {
	echo "base-$series-$(up_pkgver | tr '~:' '__')"
}

# The identity of this checkout's author, for the commits and Signed-off-by.
up_ident() {
	git -C "$top" log -1 --format='%an%n%ae' HEAD
}

up_git() {
	git -C "$up_repo" -c user.name="$up_name" -c user.email="$up_email" \
		-c core.autocrlf=false -c advice.detachedHead=false "$@"
}

# up_base: the scratch repository with the base commit, unpacked from the
# tarball only when no commit is tagged with the package's version.
up_base() {
	local tag
	tag=$(up_base_tag)
	mapfile -t _id < <(up_ident)
	up_name=${_id[0]}
	up_email=${_id[1]}
	if [ -d "$up_repo/.git" ] && up_git rev-parse -q --verify "refs/tags/$tag" >/dev/null; then
		return 0
	fi
	echo "$prog: unpacking $up_tarball ($(up_pkgver)) into $up_repo" >&2
	# The check's worktree belongs to the old repository: it goes too.
	rm -rf "$up_repo" "$up_out/check-$series"
	mkdir -p "$up_repo"
	tar -xf "$up_tarball" -C "$up_repo" --strip-components=1
	up_git init -q -b "base-$series"
	# Everything the tarball holds, ignored patterns or not.
	up_git add -A -f .
	GIT_AUTHOR_DATE="@0 +0000" GIT_COMMITTER_DATE="@0 +0000" \
		up_git commit -q --no-verify -m "Linux $series as Debian's linux-source-$series $(up_pkgver)"
	up_git tag "$tag"
}

# up_have: the LEGO_HAVE_* flags (without the prefix) of the series' tree,
# from the top-level Kbuild's own probes (drivers/lego/probes), run by
# kbuild on a configured tree of the same source: the test kernel's if it is
# cached, else a prepared x86_64_defconfig tree (build-cross-tree.sh x86).
up_have() {
	local ktree m
	ktree=$("$top/tests/kernel/build-kernel.sh" --tree-only "$series" 2>/dev/null) ||
		ktree=$("$top/tests/kernel/build-cross-tree.sh" x86 "$series") || return 1
	m=$(mktemp -d)
	echo 'include $(LEGO_SRC)/Kbuild' >"$m/Kbuild"
	make -s -C "$ktree" M="$m" LEGO_SRC="$top" LEGO_PRINT_HAVE=1 modules 2>&1 |
		sed -n 's/^lego-have: //p' | head -n 1
	rm -rf "$m"
}
