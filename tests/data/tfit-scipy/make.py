"""Writes the t-fit reference files: 1000 t draws each, at three scales, with scipy's
`t.fit` answer in the header (tests/earth.rs checks glint's MLE against it).

    pip install numpy scipy && python3 tests/data/tfit-scipy/make.py
"""
import os

import numpy as np
import scipy
import scipy.stats as st

here = os.path.dirname(os.path.abspath(__file__))
rng = np.random.default_rng(35)
for scale, name in [(1.0, "deg"), (np.pi / 180, "rad"), (3e-5, "tiny")]:
    x = st.t.rvs(df=15, loc=0.2 * scale, scale=0.13 * scale, size=1000, random_state=rng)
    nu, mu, sigma = st.t.fit(x)
    nll = -st.t.logpdf(x, nu, loc=mu, scale=sigma).sum()
    with open(os.path.join(here, f"{name}.txt"), "w") as f:
        f.write(f"# 1000 draws of a t distribution (nu 15, mu {0.2 * scale:.17g}, "
                f"sigma {0.13 * scale:.17g}), numpy default_rng(35)\n")
        f.write(f"# scipy {scipy.__version__} scipy.stats.t.fit: nu {nu:.17g} mu {mu:.17g} "
                f"sigma {sigma:.17g} nll {nll:.17g}\n")
        for v in x:
            f.write(f"{v:.17g}\n")
    print(name, nu, mu, sigma, nll)
