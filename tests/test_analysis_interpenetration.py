"""Interpenetration statistics and the expansion coefficient k (docs/method/analysis.md#interpenetration-and-the-expansion-coefficient-k)."""

from __future__ import annotations

import math

import pytest
from packing_builders import cubic_cubes, single, sphere_column

from granpack.analysis import AnalysisWarning, Interpenetration, NotComputedError
from granpack.shapes import Sphere

SIDE, LAYERS, DELTA = 3, 8, 2e-3


def column_sums(z_min: float) -> tuple[float, float]:
    """Closed-form sums of the overlapping column, per lateral cell and per unit mass: sum f_z delta_z, sum z_p.

    Centres ``z_k = 1/2 - delta + k (1 - delta)``; the wall contact (point at z = 0) carries the whole
    weight ``L m``, the contact under grain k (point at ``z_k - (1 - delta)/2``) carries ``(L - k) m``.
    Only points and grains strictly above ``z_min`` count.
    """
    z = [0.5 - DELTA + k * (1.0 - DELTA) for k in range(LAYERS)]
    work = LAYERS * DELTA if 0.0 > z_min else 0.0
    work += sum((LAYERS - k) * DELTA for k in range(1, LAYERS) if z[k] - (1.0 - DELTA) / 2 > z_min)
    return work, sum(zk for zk in z if zk > z_min)


def test_results_raise_before_compute():
    with pytest.raises(NotComputedError):
        Interpenetration().expansion_k


def test_overlap_statistics_of_the_column():
    ip = Interpenetration(deep=1e-3).compute(sphere_column(SIDE, LAYERS, overlap=DELTA))
    assert ip.max == pytest.approx(DELTA, rel=1e-12)
    assert ip.mean == pytest.approx(DELTA, rel=1e-12)
    # one vertical (or wall) point and two lateral touching points per grain
    assert ip.fraction == pytest.approx(1 / 3)
    assert ip.fraction_deep == pytest.approx(1 / 3)


def test_k_both_ways_agree_for_the_whole_column():
    ip = Interpenetration().compute(sphere_column(SIDE, LAYERS, overlap=DELTA))
    work, moment = column_sums(-math.inf)
    expected = work / moment
    assert ip.k["work_column"] == pytest.approx(expected, rel=1e-12)
    assert ip.k["love_column"] == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(DELTA * (LAYERS + 1) / 2 / (0.5 - DELTA + (1 - DELTA) * (LAYERS - 1) / 2), rel=1e-12)


def test_study_k_counts_only_above_two_grain_sizes():
    ip = Interpenetration(n_bottom=2.0).compute(sphere_column(SIDE, LAYERS, overlap=DELTA))
    work, moment = column_sums(2.0)
    assert ip.expansion_k == pytest.approx(work / moment, rel=1e-12)
    assert ip.expansion_k < ip.k["work_column"]


def test_no_overlap_gives_k_zero():
    packing, _ = cubic_cubes(3, 12)
    ip = Interpenetration().compute(packing)
    assert ip.max == 0.0 and ip.mean == 0.0 and ip.fraction == 0.0
    assert ip.k == {"work_column": 0.0, "love_column": 0.0, "work_bulk": 0.0, "love_bulk": 0.0}


def test_no_contact_gives_nan_k_and_warning():
    with pytest.warns(AnalysisWarning, match="no contact point"):
        ip = Interpenetration().compute(single(Sphere(1.0), position=(1, 1, 3)))
    assert ip.max == 0.0
    assert all(math.isnan(v) for v in ip.k.values())
    assert math.isnan(ip.fraction)
