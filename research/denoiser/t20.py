from table import *
from filt import box
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
def inj(d,c,anti):
    rng=np.random.default_rng(12345)
    o=d['ours']; v=box(d['ours_var'].mean(-1,keepdims=True),1)
    eta=rng.standard_normal(o.shape).astype(np.float32)*np.sqrt(c*v)
    a,n=aux(d)
    r=oidn(np.maximum(o+eta,0),a,n,clean_aux=True)
    if anti: r=0.5*(r+oidn(np.maximum(o-eta,0),a,n,clean_aux=True))
    return r
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt_ca':lambda d:d['D_pt_ca'],'m5':lambda d:d['X_mix0.5_ca'],'ours':lambda d:d['ours']}
for c in [1,4,16]:
    M[f'inj{c}']=mk(f'X_inj{c}',(lambda c: lambda d: inj(d,c,False))(c))
M['inj4a']=mk('X_inj4a',lambda d: inj(d,4,True))
evaluate(M, ['cornell-box','door-ajar','sponza','engine'],budgets=[32])
