#!/usr/bin/env python3
"""Turn the benchmarks' JSON files into the results file, and print them.

    tests/bench/report.py [--out FILE] [--quick] DIR

Every ``*.json`` in DIR is one section: ``{"section": title, "figures": [...],
"notes": [...]}``, each figure ``{"name", "value", "unit", "reference",
"reference_value", "target", "met", "detail"}``. The results file (Markdown)
gets the date, the machine, the commit and the tree of drivers/ it was
measured on (tests/bench/stale.sh compares it with HEAD's), then one table per section with
each figure beside its reference, then the list of targets met and missed.
"""
import argparse
import datetime
import glob
import json
import os
import platform
import subprocess
import sys

TOP = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def fmt(value, unit=""):
    """A figure as text: numbers with at most four significant digits."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if value == 0:
            text = "0"
        elif abs(value) >= 1000:
            text = f"{value:.0f}"
        else:
            text = f"{value:.4g}"
    else:
        text = str(value)
    return f"{text} {unit}".strip() if unit else text


def met_text(met):
    return {True: "met", False: "MISSED", None: "-"}[met]


def run(cmd):
    try:
        return subprocess.run(cmd, capture_output=True, text=True, check=False,
                              cwd=TOP).stdout.strip()
    except OSError:
        return ""


def machine():
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem = ""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            kb = int(f.readline().split()[1])
            mem = f", {kb / 1048576:.0f} GiB"
    except (OSError, ValueError, IndexError):
        pass
    qemu = run(["qemu-system-x86_64", "--version"]).splitlines()
    kvm = "KVM" if os.environ.get("LEGO_VM_ACCEL") == "kvm" else "TCG (no KVM)"
    return (f"{cpu}, {os.cpu_count()} cores{mem}; host {platform.system()} "
            f"{platform.release()}; {qemu[0] if qemu else 'QEMU ?'}, {kvm}")


def load(directory):
    sections = []
    for path in sorted(glob.glob(os.path.join(directory, "*.json"))):
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
        if "section" not in data or not isinstance(data.get("figures"), list):
            raise ValueError(f"{path}: not a benchmark result (section, figures)")
        data["_file"] = os.path.basename(path)
        sections.append(data)
    return sections


def cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def run_file(directory, name):
    """A line run.sh wrote into the run's directory, or None."""
    try:
        with open(os.path.join(directory, name), encoding="utf-8") as f:
            return f.read().strip() or None
    except OSError:
        return None


def is_nxt(section):
    """The NXT benchmark's section (tests/bench/guest/nxt_bench.py)."""
    return section.get("_file") == "nxt.json"


def nxt_details(section):
    """The NXT section's details, one per measurement: its rate, p50 and p99
    figures share one detail, given once under the measurement's name (the
    figure name up to its last ": ")."""
    out, seen = [], set()
    for fig in section["figures"]:
        detail = fig.get("detail")
        if not detail or detail in seen:
            continue
        seen.add(detail)
        name = fig["name"]
        if name.endswith((": rate", ": latency p50", ": latency p99")):
            name = name.rsplit(": ", 1)[0]
        out.append({"name": name, "detail": detail})
    return out


def markdown(sections, quick, stamp, kernel, commit, drivers=None):
    lines = ["# Benchmark results", "",
             f"Measured {stamp} on: {machine()}."] + \
        ([f"Guest: the {kernel}."] if kernel else []) + [
             f"Commit `{commit}`" + (" -- **quick run** (short durations; not for comparison)." if quick else "."),
             f"Driver code: tree `{drivers or 'unknown'}` (`git rev-parse HEAD:drivers`"
             "; +changes: with uncommitted changes).",
             "",
             "Reproduce with `make bench` (all of it: the protocol cores with callgrind on the host, then one",
             "VM for the EV3 and NXT figures; `tests/bench/run.sh --help`). Timing figures come from an",
             "emulated machine and move with the host's load; instruction counts are deterministic.", ""]
    targets = []
    for s in sections:
        lines += [f"## {s['section']}", "",
                  "| Figure | Measured | Reference | Reference value | Target | |",
                  "|---|---|---|---|---|---|"]
        for fig in s["figures"]:
            unit = fig.get("unit", "")
            ref_unit = unit if isinstance(fig.get("reference_value"), (int, float)) else ""
            lines.append("| " + " | ".join(cell(c) for c in (
                fig["name"], fmt(fig.get("value"), unit), fig.get("reference") or "-",
                fmt(fig.get("reference_value"), ref_unit), fig.get("target") or "-",
                met_text(fig.get("met")))) + " |")
            if fig.get("met") is not None:
                targets.append((s["section"], fig))
        details = nxt_details(s) if is_nxt(s) else [f for f in s["figures"] if f.get("detail")]
        if details:
            lines.append("")
            for fig in details:
                lines.append(f"- {fig['name']}: {fig['detail']}")
        for note in s.get("notes", []):
            lines.append(f"- {note}")
        lines.append("")
    if targets:
        lines += ["## Targets", ""]
        for section, fig in targets:
            lines.append(f"- {met_text(fig['met'])}: {section}: {fig['name']} = "
                         f"{fmt(fig.get('value'), fig.get('unit', ''))} (target {fig.get('target')})")
        lines.append("")
    return "\n".join(lines)


def text_tables(sections):
    out = []
    for s in sections:
        out.append(f"== {s['section']}")
        rows = [("figure", "measured", "reference", "ref. value", "target")]
        for fig in s["figures"]:
            unit = fig.get("unit", "")
            ref_unit = unit if isinstance(fig.get("reference_value"), (int, float)) else ""
            rows.append((fig["name"], fmt(fig.get("value"), unit), fig.get("reference") or "-",
                         fmt(fig.get("reference_value"), ref_unit),
                         (fig.get("target") or "-") + ("" if fig.get("met") is None
                                                       else f" [{met_text(fig['met'])}]")))
        widths = [min(max(len(r[i]) for r in rows), 44) for i in range(5)]
        for r in rows:
            out.append("  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip())
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out", help="the results file to write (default: print only)")
    ap.add_argument("--quick", action="store_true", help="the figures come from a quick run")
    args = ap.parse_args()
    try:
        sections = load(args.dir)
    except (OSError, ValueError) as e:
        print(f"report: {e}", file=sys.stderr)
        return 1
    if not sections:
        print(f"report: no results in {args.dir}", file=sys.stderr)
        return 1
    # The run's start, from its directory's name (run.sh), else now.
    try:
        when = datetime.datetime.strptime(os.path.basename(os.path.normpath(args.dir)),
                                          "%Y%m%dT%H%M%SZ")
    except ValueError:
        when = datetime.datetime.now(datetime.timezone.utc)
    stamp = when.strftime("%Y-%m-%d %H:%M UTC")
    print(text_tables(sections))
    if args.out:
        # The commit and the guest kernel as run.sh noted them when the run
        # began (the results file itself is part of the tree).
        commit = run_file(args.dir, "commit") or run(["git", "describe", "--always", "--dirty"]) \
            or "unknown"
        text = markdown(sections, args.quick, stamp, run_file(args.dir, "kernel"), commit,
                        run_file(args.dir, "drivers"))
        with open(args.out, "w", encoding="utf-8") as f:
            f.write(text)
    missed = sum(1 for s in sections for f in s["figures"] if f.get("met") is False)
    print(f"report: {sum(len(s['figures']) for s in sections)} figures, {missed} targets missed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
