"""Test plug-in: writes NaN everywhere."""
import numpy as np
from denoisebench_plugin import run
run(lambda frame, params: np.full_like(frame["color"], np.nan))
