from table import *
o=lambda d: np.maximum(d['ours'],0)
def pa(d): return d['_aux']
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'D_pt_ca':lambda d:d['D_pt_ca']}
for lam in [0.25,0.5,0.75]:
    M[f'mix{lam}_ca']=mk(f'X_mix{lam}_ca', (lambda lam: lambda d: oidn(lam*d['pt']+(1-lam)*o(d), np.load(f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}.aux_alb.npy"), np.load(f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}.aux_nrm.npy"), clean_aux=True))(lam))
evaluate(M, ['cornell-box','door-ajar','glass-of-water','glossy-room'])
