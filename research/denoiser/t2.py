from table import *
from filt import box
def oracle(d, D, r, ref):
    o=d['ours'].astype(np.float64); D=d[D].astype(np.float64); w=weights(ref)[...,None]
    e=o-D; t=ref-D
    # window weight minimizing sum w*(D + a e - ref)^2 over window, a in [0,1]
    a=np.clip(box(w*e*t,r)/np.maximum(box(w*e*e,r),1e-30),0,1)
    return D+a*e
cache={}
for s in ['cornell-box','door-ajar','glass-of-water','glossy-room']:
    ref=reference(s)
    M={'D_pt':lambda d:d['D_pt'],'D_pt2n':lambda d:d['D_pt2n']}
    for D in ['D_pt','D_ours']:
        for r in [0,1,3,7]:
            M[f'or{D[2:]}{r}']=(lambda D,r: lambda d: oracle(d,D,r,ref))(D,r)
    M['ours']=lambda d:d['ours']; M['pt2n']=lambda d:d['pt2n']
    evaluate(M,[s])
