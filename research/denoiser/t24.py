from table import *
from blend import *
import pickle
def aux(d):
    c=f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}"
    return np.load(c+'.aux_alb.npy'), np.load(c+'.aux_nrm.npy')
def mix(lam): return mk(f'X_mix{lam}_ca', lambda d: oidn(lam*d['pt']+(1-lam)*np.maximum(d['ours'],0),*aux(d),clean_aux=True))
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'ours':lambda d:d['ours']}
for lam in [0.65,0.75,0.85]:
    Df=mix(lam); M[f'm{lam}']=Df
    for r in [7,11]:
        for k in [2,3]:
            for om in [0.05,0.1,0.15]:
                M[f'm{lam}|js{r}k{k}w{om}']=(lambda Df,r,k,om: lambda d: (1-om)*js(d['ours'],k*d['ours_var'],Df(d),r,'lum')[0]+om*d['ours'])(Df,r,k,om)
res=evaluate(M, SCENES, verbose=False)
pickle.dump(res,open('res_t24.pkl','wb'))
rows=[]
for m in M:
    out=[]
    for base in ['D_pt2n','D_pt2n_ca']:
      for b in BUDGETS:
        r=[res[(b,s,m)]['relmse']/min(res[(b,s,'ours')]['relmse'],res[(b,s,base)]['relmse']) for s in SCENES]
        out+= [np.exp(np.mean(np.log(r))), max(r)]
    rows.append((m,out))
rows.sort(key=lambda x: x[1][0]+x[1][2])
print('vs min(ours,D_pt2n): 32 geo max, 96 geo max || vs min(ours,D_pt2n_ca): same')
for m,o in rows[:25]: print(f'{m:22s}', ' '.join(f'{x:.3f}' for x in o[:4]),'||',' '.join(f'{x:.3f}' for x in o[4:]))
