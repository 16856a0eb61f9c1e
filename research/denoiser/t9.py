from table import *
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
V={'k9w3':['ours.k=9','ours.search_window=3'],'k25w5':['ours.k=25','ours.search_window=5'],'k49w7':['ours.k=49','ours.search_window=7']}
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'D_pt_ca':lambda d:d['D_pt_ca'],'D_ours_ca':lambda d:d['D_ours_ca'],'ours':lambda d:d['ours']}
for n,p in V.items():
    M[n]=(lambda n,p: lambda d: ours_variant(d['_s'],d['_b'],d['_seed'],'o_'+n,p))(n,p)
    M['D_'+n]=mk('D_o_'+n,(lambda n,p: lambda d: oidn(np.maximum(ours_variant(d['_s'],d['_b'],d['_seed'],'o_'+n,p),0),*aux(d),clean_aux=True))(n,p))
evaluate(M, ['cornell-box','door-ajar','glass-of-water','glossy-room'])
