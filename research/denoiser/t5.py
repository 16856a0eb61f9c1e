from table import *
from filt import box
for s in ['cornell-box','glossy-room']:
  for b in [32,96]:
    ref=reference(s); w=weights(ref)[...,None]
    out=[]
    for m in ['ours','pt','D_pt_ca']:
        r=[]
        for seed in SEEDS:
            d=data(s,b,seed); e=d[m]-ref
            r.append([ (box(e,k)**2*w).mean()/(e**2*w).mean() for k in [1,2,3,7]])
        out.append((m,np.mean(r,0)))
    # calibration of ours var
    cal=[]
    for seed in SEEDS:
        d=data(s,b,seed); cal.append(((d['ours']-ref)**2*w).mean()/(d['ours_var']*w).mean())
    print(s,b,' '.join(f'{m}: '+' '.join('%.3f'%x for x in v) for m,v in out), 'ours err/pred var %.3f'%np.mean(cal))
