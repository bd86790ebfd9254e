# Headline figures of each eval run (foreign_drape_bench stdout) into one CSV row per (run, views).
import re, sys, csv
out = csv.writer(sys.stdout)
out.writerow(["database", "members", "views", "results", "hold_within_5cm_pct", "hold_median_cm", "corners_median_cm",
              "lowest_corner_within_3cm_pct", "results_with_a_safe_corner_pct", "safe_corners", "safe_within_3cm_pct",
              "median_ms_loaded_machine"])
for spec in sys.argv[1:]:
    name, members, path = spec.split(":")
    text = open(path).read()
    for label, v in (("one image", 1), ("two images", 2)):
        m = re.search(label + r"\s+(\d+) results .*?hold within 5 cm (\d+) % \(median ([\d.]+) cm\); corners median ([\d.]+) cm; lowest corner within 3 cm (\d+) %.*?; (\d+) ms median", text)
        s = re.search(label + r"\s+at least one corner safe in (\d+) % of results; (\d+) safe corners, (\d+) % within 3 cm", text)
        out.writerow([name, members, v, m.group(1), m.group(2), m.group(3), m.group(4), m.group(5), s.group(1), s.group(2), s.group(3), m.group(6)])
