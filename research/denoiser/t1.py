# band decomposition of errors (oracle analysis)
from table import *
from table import data
def gblur(x, s):
    if s<=0: return x
    r=int(3*s+0.5); k=np.exp(-0.5*(np.arange(-r,r+1)/s)**2); k/=k.sum()
    # reflect-edge separable
    def c1(a, axis):
        pad=[(0,0)]*a.ndim; pad[axis]=(r,r)
        ap=np.pad(a,pad,mode='reflect')
        out=np.zeros_like(a,dtype=np.float64)
        for i,kv in enumerate(k):
            sl=[slice(None)]*a.ndim; sl[axis]=slice(i,i+a.shape[axis]); out+=kv*ap[tuple(sl)]
        return out
    return c1(c1(x.astype(np.float64),0),1)
sig=[1,2,4,8]
for b in [32,96]:
  for s in ['cornell-box','door-ajar','glass-of-water','glossy-room']:
    ref=reference(s); w=weights(ref)[...,None]
    acc={}
    for seed in SEEDS:
        d=data(s,b,seed)
        for m in ['ours','D_pt_ca','D_pt2n_ca','crn','pt']:
            e=d[m]-ref; prev=e
            bands=[]
            for sg in sig:
                lo=gblur(e,sg); bands.append(((prev-lo)**2*w).mean()); prev=lo
            bands.append((prev**2*w).mean())
            acc.setdefault(m,[]).append(bands)
    print(b,s,' bands: <1, 1-2, 2-4, 4-8, >8  (relMSE of band, abs x1e4)')
    for m,v in acc.items(): print('   %-8s'%m, ' '.join('%8.3f'%(x*1e4) for x in np.mean(v,0)), ' total %.3f'%(relmse_tot:=0))
