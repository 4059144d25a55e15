"""Unit conversions at the edges: inside robocal everything is mm, rad, N, N·m, kg, s and deg C."""
from __future__ import annotations

import math

DEG = math.pi / 180.0            #: radians per degree
ARCSEC = DEG / 3600.0            #: radians per arc second
GON = math.pi / 200.0            #: radians per gon
LBIN_PER_NM = 1.0 / 0.1129848    #: lb·in per N·m (1 lb·in = 0.1129848 N·m)
NM_PER_LBIN = 0.1129848          #: N·m per lb·in
G0_M_S2 = 9.80665                #: standard gravity

