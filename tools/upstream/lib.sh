# shellcheck shell=bash
# Shared by tools/upstream/series.sh and tests/upstream/check.sh. Source it
# with "top" (the checkout) and "series" (6.12) set; "prog" names the caller.

up_out=${LEGO_UPSTREAM_OUT:-$top/.build/upstream}
up_tarball=/usr/src/linux-source-$series.tar.xz
# The scratch repository: the kernel source as one base commit, tagged by the
# Debian package's version, and the series on the branch lego-$series.
up_repo=$up_out/linux-$series
up_branch=lego-$series
up_patches=$up_out/$series

up_pkgver() {
	dpkg-query -W -f '${Version}' "linux-source-$series"
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
	[ -r "$up_tarball" ] || { echo "$prog: $up_tarball missing (apt-get install linux-source-$series)" >&2; return 1; }
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
