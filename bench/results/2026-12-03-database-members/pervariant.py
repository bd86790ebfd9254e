import csv, sys
for path in sys.argv[1:]:
    rows = list(csv.DictReader(open(path + '/foreign_drapes.csv')))
    out = []
    for var in ('choi_ko', 'stiff_light', 'soft_heavy', 'heap'):
        for v in ('1', '2'):
            r = [x for x in rows if x['variant'] == var and x['views'] == v]
            ok = sum(1 for x in r if x.get('success', '1') in ('1', 'true') and 0 <= float(x['hold_error_m']) <= 0.05)
            out.append('%s/%s %d/%d' % (var, v, ok, len(r)))
    print(path, ' '.join(out))
