from table import *
from blend import *
import pickle,sys
sc=['cornell-box','door-ajar','glass-of-water','glossy-room','sponza','engine']
Ds={'m75':lambda d:d['X_mix0.75_ca'],'pt+m5':lambda d:0.5*(d['D_pt_ca']+d['X_mix0.5_ca']),'pt':lambda d:d['D_pt_ca']}
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'ours':lambda d:d['ours']}
for dn,Df in Ds.items():
    for r in [5,9]:
        for k in [1.5,2,3]:
            for om in [0,0.1,0.2]:
                M[f'{dn}|js{r}k{k}w{om}']=(lambda Df,r,k,om: lambda d: (1-om)*js(d['ours'],k*d['ours_var'],Df(d),r,'lum')[0]+om*d['ours'])(Df,r,k,om)
res=evaluate(M, sc, verbose=False)
pickle.dump(res,open('res_t19.pkl','wb'))
rows=[]
for m in M:
    out=[]
    for b in BUDGETS:
        r=[res[(b,s,m)]['relmse']/min(res[(b,s,'ours')]['relmse'],res[(b,s,'D_pt2n')]['relmse']) for s in sc]
        out+= [np.exp(np.mean(np.log(r))), max(r)]
    rows.append((m,out))
rows.sort(key=lambda x: x[1][0]+x[1][2])
for m,o in rows[:25]: print(f'{m:22s}', ' '.join(f'{x:.3f}' for x in o))
