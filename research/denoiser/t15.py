from table import *
import sys
sc=sys.argv[1].split(','); names=sys.argv[2].split(',')
M={n:(lambda n: lambda d: d[n] if n in d else np.load(f"{cdir(d['_s'],d['_b'])}/seed-{d['_seed']}.{n}.npy"))(n) for n in names}
evaluate(M, sc)
