from table import *
from filt import box
for s in ['cornell-box','door-ajar','glass-of-water','glossy-room','sponza','engine']:
  for b in [32,96]:
    ref=reference(s); w=weights(ref)[...,None]
    c=[];q=[]
    for seed in SEEDS:
        d=data(s,b,seed); e2=(d['ours']-ref)**2
        c.append((e2*w).mean()/(d['ours_var']*w).mean())
        # ratio of ours var to pt var
        q.append(((d['ours_var']*w).mean()/(d['var_pt']*w).mean()))
    print(s,b,'calib %.3f'%np.mean(c),'v_ours/v_pt %.3f'%np.mean(q))
