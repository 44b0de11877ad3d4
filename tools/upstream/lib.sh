# shellcheck shell=bash
# Shared by tools/upstream/series.sh and tests/upstream/check.sh. Source it
# with "top" (the checkout) and "series" (newest, 6.12, 6.1, ...) set; "prog"
# names the caller. "newest" becomes the series it is (7.3 today): the
# source is Debian's linux-source-SERIES, as tests/kernel/fetch-source.sh
# finds it (installed, or fetched into the kernel cache).

# shellcheck source=tests/kernel/lib.sh
. "$top/tests/kernel/lib.sh"

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

# up_base_cache: the base commit, kept in the kernel cache as a bare
# repository (loose objects, tagged like the scratch repository's base), so
# that the scratch repository of a new checkout borrows its objects (git
# clone --shared) instead of unpacking the tarball and hashing every file
# again: over two minutes of CPU, which make check spent beside its VM.
up_base_cache() {
	echo "$(kcache_dir)/upstream/$(up_base_tag).git"
}

# up_base: the scratch repository with the base commit, from the cache
# (made from the tarball the first time) when no commit is tagged with the
# package's version yet. The base commit's author and date are fixed, so
# the base (and the series' base-commit line) is the same on every machine.
up_base() {
	local tag cached tmp
	tag=$(up_base_tag)
	mapfile -t _id < <(up_ident)
	up_name=${_id[0]}
	up_email=${_id[1]}
	cached=$(up_base_cache)
	# A scratch repository that borrows from a cache that is gone is made
	# again.
	if [ -d "$up_repo/.git" ] && up_git rev-parse -q --verify "refs/tags/$tag" >/dev/null &&
		{ [ ! -f "$up_repo/.git/objects/info/alternates" ] || [ -d "$cached/objects" ]; }; then
		return 0
	fi
	if ! git --git-dir="$cached" rev-parse -q --verify "refs/tags/$tag" >/dev/null 2>&1; then
		echo "$prog: unpacking $up_tarball ($(up_pkgver)) into $cached" >&2
		rm -rf "$cached"
		mkdir -p "$(dirname "$cached")"
		tmp=$(mktemp -d "$cached.XXXXXX") || return 1
		mkdir "$tmp/tree"
		tar -xf "$up_tarball" -C "$tmp/tree" --strip-components=1 &&
			git init -q --bare -b "base-$series" "$tmp/git" &&
			# Everything the tarball holds, ignored patterns or not.
			git -C "$tmp/tree" --git-dir="$tmp/git" --work-tree=. add -A -f . &&
			GIT_AUTHOR_DATE="@0 +0000" GIT_COMMITTER_DATE="@0 +0000" \
				git -C "$tmp/tree" --git-dir="$tmp/git" --work-tree=. \
				-c user.name="Debian linux-source-$series" \
				-c user.email="debian-kernel@lists.debian.org" commit -q --no-verify \
				-m "Linux $series as Debian's linux-source-$series $(up_pkgver)" &&
			git --git-dir="$tmp/git" tag "$tag" || { rm -rf "$tmp"; return 1; }
		# Another run may have made it meanwhile: theirs is the same.
		mv -T "$tmp/git" "$cached" 2>/dev/null || true
		rm -rf "$tmp"
	fi
	rm -rf "$up_repo"
	mkdir -p "$up_out"
	git clone -q --shared --no-checkout "$cached" "$up_repo" &&
		up_git reset -q --hard "$tag"
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

# up_kunit_cases FILE...: how many KUnit cases the suites in FILEs list (the
# series' messages quote the counts; the kunit steps check that many ran).
up_kunit_cases() {
	cat "$@" | grep -c '^[[:space:]]*KUNIT_CASE'
}
