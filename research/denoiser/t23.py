from table import *
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
def robust(d, kind):
    B=load(d['_s'],d['_b'],d['_seed'],batches=True)['pt_b']  # 16,H,W,3
    L=B.mean(-1)
    if kind=='trim1':
        i=np.argmax(L,0)
        s=B.sum(0)-np.take_along_axis(B,i[None,...,None].repeat(3,-1),0)[0]
        return s/15
    if kind=='mom4':
        G=B.reshape(4,4,*B.shape[1:]).mean(1); Lg=G.mean(-1)
        o=np.argsort(Lg,0)
        mid=np.take_along_axis(G,o[1:3,...,None].repeat(3,-1),0).mean(0)
        return mid
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'D_pt_ca':lambda d:d['D_pt_ca']}
for kind in ['trim1','mom4']:
    M[kind]=mk('X_'+kind,(lambda kind: lambda d: oidn(robust(d,kind),*aux(d),clean_aux=True))(kind))
evaluate(M, ['door-ajar','glossy-room','sponza','head'])
