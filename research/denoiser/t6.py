from table import *
from blend import *
sc=['cornell-box','door-ajar','glass-of-water','glossy-room']
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'D_pt_ca':lambda d:d['D_pt_ca'],'ours':lambda d:d['ours']}
for Dn in ['D_pt_ca']:
    for r in [1,3,5]:
        M[f'js{r}']=(lambda r,Dn: lambda d: js(d['ours'],d['ours_var'],d[Dn],r)[0])(r,Dn)
        M[f'jsL{r}']=(lambda r,Dn: lambda d: js(d['ours'],d['ours_var'],d[Dn],r,'lum')[0])(r,Dn)
    for s in [2,4,8]:
        M[f'lp{s}']=(lambda s,Dn: lambda d: lowres(d['ours'],d[Dn],s))(s,Dn)
evaluate(M, sc)
