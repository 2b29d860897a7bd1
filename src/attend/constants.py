"""Named precisions shared by the library, the experiments and the command line.

"Known" quantities are not fixed outright in the papers: they get a Gaussian prior so precise that
the data cannot move them in practice. The two values used are named here, once.
"""

from __future__ import annotations

import math

#: P_theta of the model entries that are known, not learned: exp(15) ~ 3.3e6 (paper Sec. 4.2.3; the
#: prior precision of the known entries in :func:`attend.perception.learning.identify` and the
#: paper reproductions fig3, fig4, fig5 and rhythm-learning)
KNOWN_PRIOR_PRECISION = math.exp(15.0)

#: Prior precision of inputs that are measured (known) but kept among the DEM observer's unknowns:
#: exp(32) ~ 7.9e13 (the quadrotor flights of Bos et al. 2022 and ``attend estimate``'s model files;
#: also the precision of the known C entries in the Entropy 2021 identification setting)
KNOWN_INPUT_PRECISION = math.exp(32.0)
