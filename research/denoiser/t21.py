from table import *
from blend import *
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
def adapt(d,k,r,lmin):
    o=d['ours']; D0=d['D_pt_ca']
    z=box(lum((o-D0)**2),r)/np.maximum(box(lum(d['ours_var']),r),1e-30)
    lam=1-(1-lmin)*np.minimum(1,k/np.maximum(z,1e-9))
    x=lam*d['pt']+(1-lam)*np.maximum(o,0)
    return oidn(x,*aux(d),clean_aux=True)
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt_ca':lambda d:d['D_pt_ca'],'m5':lambda d:d['X_mix0.5_ca'],'m75':lambda d:d['X_mix0.75_ca'],'ours':lambda d:d['ours']}
for k,r,lm in [(2,3,0.5),(4,3,0.5),(2,3,0.4)]:
    M[f'ad{k}r{r}l{lm}']=mk(f'X_ad{k}r{r}l{lm}',(lambda k,r,lm: lambda d: adapt(d,k,r,lm))(k,r,lm))
evaluate(M, ['cornell-box','door-ajar','glass-of-water','glossy-room','sponza','engine'],budgets=[32])
