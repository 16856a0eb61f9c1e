from table import *
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
def tta(x,a,n):
    outs=[]
    for fy in (0,1):
        for fx in (0,1):
            f=lambda z: z[::-1] if fy else z
            g=lambda z: z[:,::-1] if fx else z
            F=lambda z: np.ascontiguousarray(g(f(z)))
            nn=F(n).copy()
            if fy: nn[...,1]*=1  # world-space normals: flipping the image doesn't change normals
            outs.append(F(oidn(F(x),F(a),nn,clean_aux=True)))
    return np.mean(outs,0), outs[0]
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt_ca':lambda d:d['D_pt_ca'],
   'tta_pt':mk('X_tta_pt',lambda d: tta(d['pt'],*aux(d))[0]),
   'tta_m5':mk('X_tta_m5',lambda d: tta(0.5*d['pt']+0.5*np.maximum(d['ours'],0),*aux(d))[0])}
evaluate(M, ['cornell-box','sponza','engine'],budgets=[32])
