from table import *
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
def vpt(d):
    def f():
        dd=load(d['_s'],d['_b'],d['_seed'],batches=True)
        return dd['pt_b'].var(0,ddof=1)/16
    return cached(d['_s'],d['_b'],d['_seed'],'var_pt',f)
def wins(d,c):
    o=d['ours']; s=np.sqrt(vpt(d)+d['ours_var'])
    return np.maximum(o+np.clip(d['pt']-o,-c*s,c*s),0)
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'D_pt_ca':lambda d:d['D_pt_ca']}
for c in [1.5,2.5,4]:
    M[f'W{c}']=mk(f'X_win{c}',(lambda c: lambda d: oidn(wins(d,c),*aux(d),clean_aux=True))(c))
evaluate(M, ['cornell-box','door-ajar','glass-of-water','glossy-room'])
