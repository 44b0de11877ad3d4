# shellcheck shell=bash
# Shared by tests/kernel/build-kernel.sh and build-cross-tree.sh: the cache
# entry of a prepared tree and the check of its configuration. Source it;
# "prog" names the caller in messages.

# Print the kernel cache directory.
kcache_dir() {
	echo "${LEGO_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/lego-mindstorms-linux}"
}

# kcache_lookup ENTRY TREE_ONLY: print ENTRY/linux and exit 0 if the entry
# is complete; exit 1 if it is not and only the tree was asked for; else
# return, and the caller builds it.
kcache_lookup() {
	if [ -f "$1/.done" ]; then
		echo "$1/linux"
		exit 0
	fi
	[ "$2" = 0 ] || exit 1
}

# kcache_unpack TARBALL TREE: a fresh copy of the source in TREE.
kcache_unpack() {
	rm -rf "$2"
	mkdir -p "$2"
	tar -xf "$1" -C "$2" --strip-components=1
}

# kconfig_effective FRAGMENT...: each option's setting as merge_config
# leaves it, the last fragment's winning, in the order options first appear.
kconfig_effective() {
	awk '
	/^CONFIG_[A-Za-z0-9_]+=/ { opt = $0; sub(/=.*/, "", opt) }
	/^# CONFIG_[A-Za-z0-9_]+ is not set$/ { opt = $2 }
	opt != "" { if (!(opt in line)) order[n++] = opt; line[opt] = $0; opt = "" }
	END { for (i = 0; i < n; i++) print line[order[i]] }
	' "$@"
}

# kconfig_verify CONFIG "ABSENT OPTIONS" FRAGMENT...: merge_config only
# warns, so an option of a fragment that did not survive is an error here
# (options in ABSENT do not exist on this architecture and are skipped).
# A later fragment may override an earlier one (kconfig_effective).
# Messages go to stderr; returns 1 if any option is wrong.
kconfig_verify() {
	local config=$1 absent=$2 missing=0 line opt
	shift 2
	while IFS= read -r line; do
		case "$line" in
		CONFIG_*=*)
			case " $absent " in *" ${line%%=*} "*) continue ;; esac
			grep -qxF "$line" "$config" ||
				{ echo "$prog: not set as requested: $line" >&2; missing=1; }
			;;
		"# CONFIG_"*" is not set")
			opt=${line#\# }
			opt=${opt%% *}
			! grep -q "^$opt=" "$config" ||
				{ echo "$prog: should be off: $opt" >&2; missing=1; }
			;;
		esac
	done < <(kconfig_effective "$@")
	return $missing
}
