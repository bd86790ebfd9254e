import csv,collections,math,sys
W,H=0.64,0.46
def mirrors(p):
    x,y=p; return [(x,y),(W-x,y),(x,H-y),(W-x,H-y)]
def mdist(a,b): return min(math.dist(a,m) for m in mirrors(b))
def nearest_image(p,ref): return min(mirrors(p), key=lambda m: math.dist(m,ref))
def run(path, taus=(0.005,0.01,0.02,0.04), ks=(2,3), radius=0.1):
  rows=list(csv.DictReader(open(path)))
  g=collections.defaultdict(list)
  for r in rows: g[(r['variant'],r['hold_x_m'],r['hold_y_m'],r['views'],r['azimuth_deg'])].append(r)
  for v in '12':
    keys=[k for k in g if k[3]==v]
    base=sum(float(g[k][0]['candidate_hold_error_m'])<=0.05 for k in keys)
    out=[f'views {v}: n {len(keys)} winner {base}']
    for kk in ks:
      for tau in taus:
        ok=0; errs=[]
        for k in keys:
          c=g[k][:kk]; truth=(float(k[1]),float(k[2]))
          w0=(float(c[0]['candidate_x_m']),float(c[0]['candidate_y_m'])); s0=float(c[0]['score'])
          sx=sy=sw=0
          for x in c:
            p=nearest_image((float(x['candidate_x_m']),float(x['candidate_y_m'])),w0)
            if math.dist(p,w0)>radius: continue
            w=math.exp((float(x['score'])-s0)/tau)
            sx+=w*p[0]; sy+=w*p[1]; sw+=w
          e=mdist((sx/sw,sy/sw),truth); errs.append(e); ok+=e<=0.05
        errs.sort()
        out.append(f'k{kk} tau{tau}: {ok} med {100*errs[len(errs)//2]:.1f}')
    print(' | '.join(out))
for p in sys.argv[1:]: print(p); run(p)
