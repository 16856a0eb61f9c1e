from table import *
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
def ratio(d, delta, mode):
    o=np.maximum(d['ours'],0)+delta
    q=(d['pt']+delta)/o
    if mode=='none': R=oidn(q)
    elif mode=='nrm': R=oidn(q, np.ones_like(q)*0.5, aux(d)[1], clean_aux=True)
    elif mode=='ca': R=oidn(q,*aux(d),clean_aux=True)
    return o*R-delta
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'D_pt_ca':lambda d:d['D_pt_ca'],'ours':lambda d:d['ours']}
for delta in [0.01]:
  for mode in ['none','nrm','ca']:
    M[f'R{mode}{delta}']=mk(f'X_ratio_{mode}_{delta}',(lambda delta,mode: lambda d: ratio(d,delta,mode))(delta,mode))
evaluate(M, ['cornell-box','door-ajar','glass-of-water','glossy-room'])
