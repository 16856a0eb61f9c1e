from table import *
from blend import *
import itertools
sc=['cornell-box','door-ajar','glass-of-water','glossy-room','sponza','engine']
Ds={'pt':lambda d:d['D_pt_ca'],'m5':lambda d:d['X_mix0.5_ca'],'m75':lambda d:d['X_mix0.75_ca'],
    'pt+m5':lambda d:0.5*(d['D_pt_ca']+d['X_mix0.5_ca']),'m5+Do':lambda d:0.5*(d['X_mix0.5_ca']+d['D_ours_ca'])}
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'ours':lambda d:d['ours']}
for dn,Df in Ds.items():
    M[dn]=Df
    for r,k in [(3,2),(7,1),(7,2),(11,2)]:
        M[f'{dn}|js{r}k{k}']=(lambda Df,r,k: lambda d: js(d['ours'],k*d['ours_var'],Df(d),r,'lum')[0])(Df,r,k)
res=evaluate(M, sc, verbose=False)
import pickle; pickle.dump(res,open('res_t16.pkl','wb'))
for b in BUDGETS:
    print(f'== {b}: ratio to min(ours, D_pt2n) per scene | geomean | max ; also geomean vs D_pt2n_ca')
    for m in M:
        r=[res[(b,s,m)]['relmse']/min(res[(b,s,'ours')]['relmse'],res[(b,s,'D_pt2n')]['relmse']) for s in sc]
        r2=[res[(b,s,m)]['relmse']/min(res[(b,s,'ours')]['relmse'],res[(b,s,'D_pt2n_ca')]['relmse']) for s in sc]
        print(f'{m:16s}'+' '.join(f'{x:6.3f}' for x in r)+f' | {np.exp(np.mean(np.log(r))):6.3f} | {max(r):6.3f} || {np.exp(np.mean(np.log(r2))):6.3f} {max(r2):6.3f}')
