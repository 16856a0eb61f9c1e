from table import *
from blend import *
import pickle,sys
sc=SCENES
Ds={'m75':lambda d:d['X_mix0.75_ca'],'pt+m5':lambda d:0.5*(d['D_pt_ca']+d['X_mix0.5_ca']),'pt':lambda d:d['D_pt_ca'],'m5':lambda d:d['X_mix0.5_ca']}
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'ours':lambda d:d['ours']}
for dn,Df in Ds.items():
    M[dn]=Df
    for r in [5,9]:
        for k in [1.5,2,3]:
            for om in [0,0.1]:
                M[f'{dn}|js{r}k{k}w{om}']=(lambda Df,r,k,om: lambda d: (1-om)*js(d['ours'],k*d['ours_var'],Df(d),r,'lum')[0]+om*d['ours'])(Df,r,k,om)
res=evaluate(M, sc, verbose=False)
pickle.dump(res,open('res_t22.pkl','wb'))
def summ(sc_sub, base):
    rows=[]
    for m in M:
        out=[]
        for b in BUDGETS:
            r=[res[(b,s,m)]['relmse']/min(res[(b,s,'ours')]['relmse'],res[(b,s,base)]['relmse']) for s in sc_sub]
            out+= [np.exp(np.mean(np.log(r))), max(r)]
        rows.append((m,out))
    rows.sort(key=lambda x: x[1][0]+x[1][2])
    return rows
for base in ['D_pt2n','D_pt2n_ca']:
    print('### vs min(ours,',base,')  cols: 32 geo, 32 max, 96 geo, 96 max | same on first 6 | on head,teapots')
    A=dict(summ(sc,base)); B=dict(summ(sc[:6],base)); C=dict(summ(sc[6:],base))
    for m,o in summ(sc,base)[:20]: print(f'{m:22s}', ' '.join(f'{x:.3f}' for x in o),'|',' '.join(f'{x:.3f}' for x in B[m]),'|',' '.join(f'{x:.3f}' for x in C[m]))
