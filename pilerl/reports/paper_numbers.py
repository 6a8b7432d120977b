"""The revised paper's closed-loop success rates [%] (real wheel loader, winter tests).

Keys: (controller, sensor set, training dataset, test). Sensor sets as in ``conf/sensors``:
``s`` = <theta1, theta2, p_d>, ``s_pt`` = s + p_t, ``s_pt_sprime`` = s + p_t with the
attention sensors s'. Tests: ``summer`` / ``winter``. Attempts per cell: Table II 15
(winter), Table III about 30, Table IV not stated.
"""

from __future__ import annotations

# Table II (Exp. 1): trained on summer D_II with s, tested in summer and in winter.
TABLE_II = {
    ("nnet", "s", "d_ii", "summer"): 0,
    ("rf", "s", "d_ii", "summer"): 80,
    ("nnetv2", "s", "d_ii", "summer"): 12,
    ("nnet", "s", "d_ii", "winter"): 0,
    ("rf", "s", "d_ii", "winter"): 40,
    ("nnetv2", "s", "d_ii", "winter"): 0,
}

# Table III (Exp. 2): D_II vs D_I, with and without p_t; tested in winter.
TABLE_III = {
    ("rf", "s", "d_ii", "winter"): 40,
    ("rf", "s", "d_i", "winter"): 30,
    ("rf", "s_pt", "d_ii", "winter"): 86,
    ("rf", "s_pt", "d_i", "winter"): 87,
    ("nnet", "s", "d_ii", "winter"): 0,
    ("nnet", "s", "d_i", "winter"): 0,
    ("nnet", "s_pt", "d_ii", "winter"): 0,
    ("nnet", "s_pt", "d_i", "winter"): 0,
    ("nnetv2", "s", "d_ii", "winter"): 0,
    ("nnetv2", "s", "d_i", "winter"): 56,
    ("nnetv2", "s_pt", "d_ii", "winter"): 0,
    ("nnetv2", "s_pt", "d_i", "winter"): 76,
}

# Table IV (Exp. 3): attention; tested in winter. NNetV2 "with s'" reads s and s' as inputs.
TABLE_IV = {
    ("nnetv2", "s", "d_i", "winter"): 56,
    ("nnetv2", "s", "d_ii", "winter"): 0,
    ("annet", "s", "d_i", "winter"): 48,
    ("annet", "s", "d_ii", "winter"): 0,
    ("dannet", "s", "d_i", "winter"): 24,
    ("dannet", "s", "d_ii", "winter"): 0,
    ("nnetv2", "s_pt", "d_i", "winter"): 76,
    ("nnetv2", "s_pt", "d_ii", "winter"): 0,
    ("annet", "s_pt", "d_i", "winter"): 100,
    ("annet", "s_pt", "d_ii", "winter"): 60,
    ("dannet", "s_pt", "d_i", "winter"): 100,
    ("dannet", "s_pt", "d_ii", "winter"): 100,
    ("nnetv2", "s_pt_sprime", "d_i", "winter"): 0,
    ("nnetv2", "s_pt_sprime", "d_ii", "winter"): 0,
    ("annet", "s_pt_sprime", "d_i", "winter"): 100,
    ("annet", "s_pt_sprime", "d_ii", "winter"): 80,
    ("dannet", "s_pt_sprime", "d_i", "winter"): 100,
    ("dannet", "s_pt_sprime", "d_ii", "winter"): 100,
}
