#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The report of tools/fault_soak.sh: per fault, the force at the display before it, how long
until zero force, how long from its end until force again; the recording read by Debian's rosbag;
resident memory and descriptors at the start and the end. Usage: fault_soak_report.py OUTDIR"""
import bisect
import csv
import os
import shutil
import statistics
import sys

WARMUP_S = 60  # resident memory is compared from here (the pools and caches are full by then)


def load_display(path):
    t, p, port = [], [], []
    with open(path, newline="") as f:
        for row in csv.reader(f):
            if len(row) != 5 or row[0] == "rx_ns":
                continue  # the header (again after each reopening) or a line cut by a kill
            try:
                t.append(int(row[0]))
                port.append(int(row[1]))
                p.append(float(row[2]))
            except ValueError:
                continue
    return t, p, port


def first_at(t, p, since_ns, until_ns, want_zero):
    i = bisect.bisect_left(t, since_ns)
    while i < len(t) and t[i] <= until_ns:
        if (p[i] == 0.0) == want_zero:
            return t[i]
        i += 1
    return None


def window(t, p, a_ns, b_ns):
    return p[bisect.bisect_left(t, a_ns):bisect.bisect_right(t, b_ns)]


def ms(a, b):
    return "-" if a is None or b is None else f"{(a - b) / 1e6:.1f}"


def fault_rows(outdir, t, p):
    rows = []
    with open(os.path.join(outdir, "faults.csv"), newline="") as f:
        for r in csv.DictReader(f):
            s, e = int(r["start_ns"]), int(r["end_ns"])
            before = window(t, p, s - 1_000_000_000, s)
            pressing = statistics.median(before) if before else 0.0
            name = r["fault"]
            zero = rec = None
            note = ""
            if name == "display_closed":
                rec = first_at(t, p, e, e + 10_000_000_000, False)
                note = "display absent during the fault: no zero can reach it"
            elif name in ("loss20", "disk_full"):
                until = e if name == "loss20" else s + 10_000_000_000
                during = window(t, p, s, until)
                zeros = sum(1 for v in during if v == 0.0)
                note = (f"rides through: {zeros} of {len(during)} commands zero, median "
                        f"{statistics.median(during) if during else 0:.2f} N")
                zero = first_at(t, p, s, until, True)
                rec = e if zero is None else first_at(t, p, max(e, zero), e + 10_000_000_000, False)
            else:
                zero = first_at(t, p, s, e + 10_000_000_000, True)
                rec = first_at(t, p, e, e + 10_000_000_000, False)
            rows.append(dict(name=name, start=s, end=e, pressing=pressing, zero=zero, rec=rec,
                             note=note, before=r["pressing_before"]))
    return rows


def open_bag(path):
    import rosbag  # Debian's python3-rosbag
    try:
        return rosbag.Bag(path), False
    except rosbag.ROSBagUnindexedException:
        fixed = path + ".reindexed.bag"
        shutil.copyfile(path, fixed)
        with rosbag.Bag(fixed, "a", allow_unindexed=True) as b:
            for _ in b.reindex():
                pass
        return rosbag.Bag(fixed), True


def bag_lines(outdir, rows):
    path = os.path.join(outdir, "session.bag")
    if not os.path.exists(path):
        return ["- recording: no session.bag was copied out of the tmpfs"]
    try:
        bag, reindexed = open_bag(path)
    except Exception as e:  # the report names any failure to read it
        return [f"- recording: **not readable** by rosbag: {type(e).__name__}: {e}"]
    with bag:
        info = bag.get_type_and_topic_info().topics
        counts = {k: v.message_count for k, v in info.items()}
        last_ns = 0
        n = 0
        for _, _, when in bag.read_messages():
            n += 1
            last_ns = max(last_ns, when.to_nsec())
    out = [f"- recording: {os.path.getsize(path) / 2**20:.0f} MiB, {n} messages read to the end by "
           f"Debian's python3-rosbag{' after reindex (no index: the disk was full)' if reindexed else ''}"]
    out.append("  - per topic: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    full = [r for r in rows if r["name"] == "disk_full"]
    if full:
        out.append(f"  - last message {ms(last_ns, full[0]['start'])} ms after the disk was filled")
    return out


def fd_window(rows, key, first):
    """The descriptors' range over the first or the last five minutes of samples: a single sample
    catches transient ones (a picture being written, a reconnect's socket)."""
    t = [int(r["t_s"]) for r in rows]
    if first:
        sel = [r for r in rows if int(r["t_s"]) <= t[0] + 300]
    else:
        sel = [r for r in rows if int(r["t_s"]) >= t[-1] - 300]
    v = [int(r[key]) for r in sel if r[key]]
    return f"{min(v)}-{max(v)}" if v else "-"


def resource_lines(outdir):
    rows = []
    with open(os.path.join(outdir, "resources.csv"), newline="") as f:
        for r in csv.DictReader(f):
            rows.append(r)
    out = []
    local = [r for r in rows if r["local_kb"] and int(r["t_s"]) >= WARMUP_S]
    if len(local) > 4:
        a, b = local[0], local[-4]  # the last seconds are the station's shutdown
        growth = 100.0 * (int(b["local_kb"]) - int(a["local_kb"])) / int(a["local_kb"])
        out.append(f"- telex-local: resident {int(a['local_kb']) / 1024:.1f} MiB at {a['t_s']} s, "
                   f"{int(b['local_kb']) / 1024:.1f} MiB at {b['t_s']} s ({growth:+.2f} %); "
                   f"descriptors over the first 5 min {fd_window(local[:-3], 'local_fds', True)}, "
                   f"over the last 5 min {fd_window(local[:-3], 'local_fds', False)}")
    by_pid = {}
    for r in rows:
        if r["remote_kb"]:
            by_pid.setdefault(r["remote_pid"], []).append(r)
    if by_pid:
        pid, runs = max(by_pid.items(), key=lambda kv: len(kv[1]))
        runs = runs[min(30, len(runs) - 1):]
        a, b = runs[0], runs[-1]
        growth = 100.0 * (int(b["remote_kb"]) - int(a["remote_kb"])) / int(a["remote_kb"])
        out.append(f"- telex-remote (its longest life, {len(by_pid)} started in all): resident "
                   f"{int(a['remote_kb']) / 1024:.1f} MiB at {a['t_s']} s, "
                   f"{int(b['remote_kb']) / 1024:.1f} MiB at {b['t_s']} s ({growth:+.2f} %); "
                   f"descriptors over its first 5 min {fd_window(runs, 'remote_fds', True)}, "
                   f"over its last 5 min {fd_window(runs, 'remote_fds', False)}")
    return out


def main():
    outdir = sys.argv[1]
    t, p, _ = load_display(os.path.join(outdir, "display.csv"))
    rows = fault_rows(outdir, t, p)
    t0 = rows[0]["start"] if rows else 0
    print("| # | at (s) | fault | force before (N) | to zero (ms) | end to force again (ms) | note |")
    print("|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows, 1):
        print(f"| {i} | {(r['start'] - t0) / 1e9:.0f} | {r['name']} | {r['pressing']:.2f} | "
              f"{ms(r['zero'], r['start'])} | {ms(r['rec'], r['end'])} | {r['note']} |")
    print()
    by = {}
    for r in rows:
        by.setdefault(r["name"], []).append(r)
    print("| fault | n | to zero: median / max (ms) | to force again: median / max (ms) |")
    print("|---|---|---|---|")
    for name, rs in by.items():
        z = [(r["zero"] - r["start"]) / 1e6 for r in rs if r["zero"] is not None]
        g = [(r["rec"] - r["end"]) / 1e6 for r in rs if r["rec"] is not None]
        zs = f"{statistics.median(z):.1f} / {max(z):.1f}" if z else "-"
        gs = f"{statistics.median(g):.1f} / {max(g):.1f}" if g else "never"
        print(f"| {name} | {len(rs)} | {zs} | {gs} |")
    print()
    for line in bag_lines(outdir, rows) + resource_lines(outdir):
        print(line)
    rc_path = os.path.join(outdir, "local.rc")
    if os.path.exists(rc_path):
        print(f"- telex-local exit code {open(rc_path).read().strip()}")


if __name__ == "__main__":
    main()
