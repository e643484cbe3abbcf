"""The rows of the pose tables (scripts/registration.sh, registration-sim.sh,
kiss-peer.sh): runs grouped by their labels, medians over each group.

Each input line is tab-separated: the row's label cells, then a run's
`isoline eval --reference` JSON (`-` without a reference: the pose columns stay empty),
its `isoline map --stats` JSON, and the milliseconds a scan measured outside isoline (a
peer's wall time, standing in the whole run's CPU column; `-` for isoline's own runs).

Columns after the labels: runs, ATE m, RPE over 1 m and 10 m (m, deg), static returns
within 5 cm, share seen through, loops closed, CPU ms a scan (registration / all).

Usage: pose-rows.py ROWS.tsv
"""
import json
import statistics
import sys


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def cell(value, fmt):
    return "" if value is None else fmt.format(value)


def main():
    groups = {}
    for line in open(sys.argv[1]):
        *labels, eval_path, stats_path, ms = line.rstrip("\n").split("\t")
        e = json.load(open(eval_path)) if eval_path != "-" else {}
        s = json.load(open(stats_path))
        groups.setdefault(tuple(labels), []).append((e, s, None if ms == "-" else float(ms)))
    for labels, runs in groups.items():
        g = lambda fn: median([fn(e, s, ms) for e, s, ms in runs])
        rpe = lambda k, f: g(lambda e, s, ms: e["rpe"][k][f] if "rpe" in e else None)
        reg = lambda e, s, ms: s.get("registration", {})
        loops = g(lambda e, s, ms: reg(e, s, ms).get("loops"))
        cpu_reg = g(lambda e, s, ms: reg(e, s, ms).get("cpu_ms_per_scan"))
        cpu_all = g(lambda e, s, ms: ms if ms is not None else s.get("cpu_ms_per_scan"))
        cpu = f"{cell(cpu_reg, '{:.1f}')} / {cell(cpu_all, '{:.1f}')}"
        print(
            f"| {' | '.join(labels)} | {len(runs)} | {cell(g(lambda e, s, ms: e.get('ate_m')), '{:.3f}')} "
            f"| {cell(rpe(0, 'translation_m'), '{:.3f}')}, {cell(rpe(0, 'heading_deg'), '{:.2f}')} "
            f"| {cell(rpe(1, 'translation_m'), '{:.3f}')}, {cell(rpe(1, 'heading_deg'), '{:.2f}')} "
            f"| {cell(g(lambda e, s, ms: 100 * s['scores']['static_within']), '{:.1f}%')} "
            f"| {cell(g(lambda e, s, ms: 100 * s['scores']['seen_through']), '{:.2f}%')} "
            f"| {cell(loops, '{:.0f}')} | {cpu} |"
        )


if __name__ == "__main__":
    main()
