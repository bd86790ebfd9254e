import csv, sys, statistics
timing = {"wall_s", "ms_per_step", "assembly_ms_per_step", "solve_ms_per_step", "collision_ms_per_step"}
def load(d):
    with open(d + "/sim_benchmark.csv") as f:
        return list(csv.DictReader(f))
runs = sys.argv[1:]
data = {r: load(r) for r in runs}
base = data[runs[0]]
for r in runs[1:]:
    rows = data[r]
    assert len(rows) == len(base), (r, len(rows), len(base))
    diff = 0
    for a, b in zip(base, rows):
        for k in a:
            if k in timing or k == "note": continue
            if a[k] != b[k]:
                diff += 1
                print("DIFF", r, a["model"], a["integrator"], a["policy"], a["hold"], k, a[k], b[k])
    print(r, "rows", len(rows), "non-timing fields differing from", runs[0], ":", diff)
# per-row wall ratio new/old for interleaved pairs (old_i, new_i)
olds = [r for r in runs if r.startswith("old")]
news = [r for r in runs if r.startswith("new")]
ratios = []
for o, n in zip(olds, news):
    so = sum(float(x["wall_s"]) for x in data[o]); sn = sum(float(x["wall_s"]) for x in data[n])
    ratios.append(sn / so)
    print(f"pair {o}/{n}: total wall old {so:.1f} s new {sn:.1f} s ratio new/old {sn/so:.3f}")
if ratios:
    print("ratio new/old min/median/max: %.3f / %.3f / %.3f" % (min(ratios), statistics.median(ratios), max(ratios)))
