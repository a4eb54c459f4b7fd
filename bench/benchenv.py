"""
What the benchmark scripts share: one BLAS thread, and where the real logs are.

Import it before numpy: the BLAS thread pools read their variables once,
when numpy loads. One thread per process keeps the figures those of one
core, beside references run the same way.
"""

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ[_var] = '1'

#: The real logs beside the checkout (``../shared/data/real``); absent on a bare clone.
REAL = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(
    __file__)))), 'shared', 'data', 'real')
