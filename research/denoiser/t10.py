# statistical oracle: per-pixel weights from the true expected MSE of D (from the 4 seeds) and of ours
from table import *
from filt import box
sc=['cornell-box','door-ajar','glass-of-water','glossy-room']
for b in [32,96]:
    for s in sc:
        ref=reference(s); w=weights(ref)[...,None]
        ds=[data(s,b,seed) for seed in SEEDS]
        out={}
        for Dn in ['D_pt_ca','D_pt2n_ca']:
            mD=np.mean([(d[Dn]-ref)**2 for d in ds],0)
            mO=np.mean([(d['ours']-ref)**2 for d in ds],0)
            for r in [0,2]:
                a=box(mD,r); c=box(mO,r)
                wt=a/(a+c)
                out[f'{Dn}_r{r}']=np.mean([((d[Dn]+wt*(d['ours']-d[Dn])-ref)**2*w).mean() for d in ds])
            out[Dn]=np.mean([((d[Dn]-ref)**2*w).mean() for d in ds])
        p=np.mean([((d['pt2n']-ref)**2*w).mean() for d in ds])
        print(b,s,' '.join(f'{k} {v/p:.4f}' for k,v in out.items()))
