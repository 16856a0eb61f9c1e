from table import *
from blend import *
sc=['cornell-box','door-ajar','glass-of-water','glossy-room']
M={'D_pt2n':lambda d:d['D_pt2n'],'D_pt2n_ca':lambda d:d['D_pt2n_ca'],'D_pt_ca':lambda d:d['D_pt_ca']}
for k in [1,2,4]:
    for r in [3,7]:
        M[f'js{r}k{k}']=(lambda r,k: lambda d: js(d['ours'],k*d['ours_var'],d['D_pt_ca'],r,'lum')[0])(r,k)
evaluate(M, sc)
