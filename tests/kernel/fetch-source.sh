#!/usr/bin/env bash
# The source of a kernel series from Debian's linux-source-X.Y packages.
#
#   tests/kernel/fetch-source.sh SERIES    SERIES: X.Y, or "newest"
#
# Prints one line, "SERIES VERSION TARBALL": the series (newest resolved),
# the package's Debian version and the path of its linux-source-X.Y.tar.xz.
#
# A series that the system's apt installed (tests/install-deps.sh installs
# 6.1 and 6.12 from Debian 12) is taken from /usr/src as it is. Any other
# series, and "newest", comes from trixie-backports and sid through a
# private apt configuration under the cache ($LEGO_CACHE/apt: its own
# sources list, package lists, download cache and dpkg status; packages
# verified with the installed debian-archive-keyring): the system's apt
# sources and state stay untouched, and nothing is installed. The package
# is downloaded once; its tarball is kept in $LEGO_CACHE/src as
# linux-source-X.Y_VERSION.tar.xz.
#
# "newest" is the highest X.Y that either suite serves, at the highest
# version that is not a release candidate (~rc). The package lists are
# refreshed at most once every LEGO_APT_MAX_AGE seconds (default 6 hours);
# a failed refresh falls back on the lists already there, so a warm cache
# works offline.
set -euo pipefail

series=${1:?usage: $0 SERIES|newest}
here=$(cd "$(dirname "$0")" && pwd)
prog=fetch-source
# shellcheck source=tests/kernel/lib.sh
. "$here/lib.sh"
cache=$(kcache_dir)

if [ "$series" != newest ] && [ -r "/usr/src/linux-source-$series.tar.xz" ] &&
	ver=$(dpkg-query -W -f '${Version}' "linux-source-$series" 2>/dev/null) && [ -n "$ver" ]; then
	echo "$series $ver /usr/src/linux-source-$series.tar.xz"
	exit 0
fi

keyring=/usr/share/keyrings/debian-archive-keyring.gpg
[ -r "$keyring" ] || { echo "$prog: $keyring missing (apt-get install debian-archive-keyring)" >&2; exit 1; }
apt=$cache/apt
mkdir -p "$apt/etc/apt.conf.d" "$apt/etc/preferences.d" "$apt/etc/trusted.gpg.d" \
	"$apt/lists/partial" "$apt/archives/partial" "$cache/src"
cat >"$apt/etc/sources.list" <<EOF
deb [signed-by=$keyring] http://deb.debian.org/debian trixie-backports main
deb [signed-by=$keyring] http://deb.debian.org/debian sid main
EOF
: >>"$apt/status"
cat >"$apt/apt.conf" <<EOF
Dir::Etc "$apt/etc";
Dir::Etc::SourceList "$apt/etc/sources.list";
Dir::Etc::SourceParts "$apt/etc/sources.list.d";
Dir::Etc::Parts "$apt/etc/apt.conf.d";
Dir::Etc::Preferences "$apt/etc/preferences";
Dir::Etc::PreferencesParts "$apt/etc/preferences.d";
Dir::Etc::TrustedParts "$apt/etc/trusted.gpg.d";
Dir::State::Lists "$apt/lists";
Dir::State::status "$apt/status";
Dir::Cache "$apt/cache";
Dir::Cache::Archives "$apt/archives";
Dir::Cache::pkgcache "";
Dir::Cache::srcpkgcache "";
APT::Architecture "amd64";
APT::Architectures { "amd64"; };
Acquire::Languages "none";
Acquire::IndexTargets::deb::DEP-11::DefaultEnabled "false";
Acquire::IndexTargets::deb::DEP-11-icons::DefaultEnabled "false";
Acquire::IndexTargets::deb::DEP-11-icons-small::DefaultEnabled "false";
APT::Sandbox::User "root";
// Mirrors may serve a snapshot whose Release files are past their
// Valid-Until date; the signatures are still checked against the keyring.
Acquire::Check-Valid-Until "false";
Acquire::Check-Date "false";
EOF
export APT_CONFIG=$apt/apt.conf
mkdir -p "$apt/cache"

max_age=${LEGO_APT_MAX_AGE:-21600}
stamp=$apt/updated
if [ ! -f "$stamp" ] || [ $(( $(date +%s) - $(stat -c %Y "$stamp") )) -gt "$max_age" ]; then
	if apt-get -qq update >"$apt/update.log" 2>&1; then
		touch "$stamp"
	elif [ -f "$stamp" ]; then
		echo "$prog: apt-get update failed, using the lists of $(date -r "$stamp" +%F) ($apt/update.log)" >&2
	else
		echo "$prog: apt-get update failed ($apt/update.log):" >&2
		tail -n 5 "$apt/update.log" >&2
		exit 1
	fi
fi

# best_version PACKAGE: the highest version of PACKAGE the lists have,
# release candidates left out.
best_version() {
	apt-cache madison "$1" 2>/dev/null | awk -F'|' '{ gsub(/ /, "", $2); print $2 }' |
		grep -v '~rc' | sort -u | {
		best=
		while read -r v; do
			if [ -z "$best" ] || dpkg --compare-versions "$v" gt "$best"; then best=$v; fi
		done
		echo "$best"
	}
}

if [ "$series" = newest ]; then
	series=
	for s in $(apt-cache search --names-only '^linux-source-[0-9]+\.[0-9]+$' |
		sed -n 's/^linux-source-\([0-9]*\.[0-9]*\) .*/\1/p' | sort -V -r); do
		if [ -n "$(best_version "linux-source-$s")" ]; then series=$s; break; fi
	done
	[ -n "$series" ] || { echo "$prog: no linux-source-X.Y package in the lists" >&2; exit 1; }
fi
pkg=linux-source-$series
ver=$(best_version "$pkg")
[ -n "$ver" ] || { echo "$prog: no version of $pkg in trixie-backports or sid" >&2; exit 1; }
tarball=$cache/src/${pkg}_${ver}.tar.xz

if [ ! -r "$tarball" ]; then
	echo "$prog: downloading $pkg $ver" >&2
	rm -f "$apt/archives/${pkg}_"*.deb
	(cd "$apt/archives" && apt-get -qq download "$pkg=$ver") >&2
	deb=$(ls "$apt/archives/${pkg}_"*.deb)
	# The package holds the tarball and nothing else of use here.
	dpkg-deb --fsys-tarfile "$deb" | tar -xO "./usr/src/$pkg.tar.xz" >"$tarball.part"
	mv "$tarball.part" "$tarball"
	rm -f "$deb"
fi
echo "$series $ver $tarball"
