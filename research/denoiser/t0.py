from table import *
M = {k: (lambda k: lambda d: d[k])(k) for k in ['pt2n','ours','D_pt2n','D_pt2n_ca','D_pt','D_pt_ca','D_avg','D_ours','D_ours_ca','D_ours_na','D_ours_dm','D_ours_fast']}
evaluate(M, bias=True)
