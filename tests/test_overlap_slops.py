"""Overlap slops scaled by the pair (``overlap.slop_scale = "pair"``) on hand-built sphere contacts.

A large sphere (d = 1) and a small one (d = 0.2) overlap on a floor: with the slops in d the
small grain's overlap is within them, with the slops scaled by the pair (factor 0.2) the same
overlap is beyond them, and the recovery and the projection act on it; a pair of large grains is
treated alike by both rules.
"""

import numpy as np
import pytest

from test_config import pinacoids
from test_nscd_solver import H, sphere_contacts, sphere_state

from granpack.config import load_config_dict
from granpack.nscd import StepParameters, advance, assemble, predict
from granpack.nscd.problem import body_slop_scale, pair_slop_scale
from granpack.settling import step_parameters


def test_the_slop_factor_of_a_pair_is_its_smaller_grain_over_the_largest():
    scale = body_slop_scale(np.array([0.5, 0.1, 0.25]))
    np.testing.assert_array_equal(scale, [1.0, 0.2, 0.5, 1.0])  # last row: the wall
    pair = pair_slop_scale(np.array([0, 0, 2, 1]), np.array([1, 2, -1, -1]), scale)
    np.testing.assert_array_equal(pair, [0.2, 0.5, 0.5, 0.2])


def _overlapping_pair(overlap, small=0.2):
    """Two spheres at rest side by side, d = 1 and d = ``small``, overlapping by ``overlap`` d."""
    state = sphere_state([[2.0, 2.0, 3.0], [2.5 + 0.5 * small - overlap, 2.0, 3.0]], [1.0, small])
    return state, sphere_contacts(state, [(1, 0, (0, 0, 0))], [])


@pytest.mark.parametrize("by_pair, expected", [(False, 0.0), (True, -0.2 * (3e-4 - 0.2 * 5e-4) / H)])
def test_the_recovery_pushes_back_the_overlap_beyond_the_pairs_slop(by_pair, expected):
    state, contacts = _overlapping_pair(3e-4)
    zero = np.zeros((3, 6))
    inv_mass = np.append(1.0 / state.mass, 0.0)
    problem = assemble(contacts, state.position, inv_mass, np.zeros((3, 6)), zero, zero, H,
                       recovery_slop=5e-4, recovery_rate=0.2, recovery_speed=0.05,
                       slop_scale=body_slop_scale(state.radius) if by_pair else None)
    assert problem.offset[0] == pytest.approx(expected, abs=1e-11)  # the gap from positions near 2.5 d


def test_a_pair_of_equal_large_grains_is_treated_alike_by_both_rules():
    state = sphere_state([[2.0, 2.0, 3.0], [3.0 - 8e-4, 2.0, 3.0], [5.0, 5.0, 3.0]], [1.0, 1.0, 0.2])
    contacts = sphere_contacts(state, [(1, 0, (0, 0, 0))], [])
    zero = np.zeros((4, 6))
    inv_mass = np.append(1.0 / state.mass, 0.0)
    kwargs = dict(recovery_slop=5e-4, recovery_rate=0.2, recovery_speed=0.05)
    plain = assemble(contacts, state.position, inv_mass, np.zeros((4, 6)), zero, zero, H, **kwargs)
    scaled = assemble(contacts, state.position, inv_mass, np.zeros((4, 6)), zero, zero, H,
                      slop_scale=body_slop_scale(state.radius), **kwargs)
    assert plain.offset[0] == scaled.offset[0] == pytest.approx(-0.2 * 3e-4 / H, rel=1e-12)


@pytest.mark.parametrize("by_pair", [False, True])
def test_the_projection_acts_on_an_overlap_beyond_the_pairs_slop(by_pair):
    # no gravity, no recovery: only the projection can move the grains (overlap 1e-3 d, slop 2e-3 d)
    state, _ = _overlapping_pair(1e-3)
    params = StepParameters(time_step=H, gravity=(0.0, 0.0, 0.0), recovery_rate=0.0, slops_by_pair=by_pair)
    pr = predict(state, params)
    contacts = sphere_contacts(pr.state, [(1, 0, (0, 0, 0))], [])
    _, info = advance(state, pr, contacts, params)
    gap = np.linalg.norm(state.position[1] - state.position[0]) - 0.6
    if by_pair:  # the pair's slop is 0.2 x 2e-3 = 4e-4: projected to 0.1 of it
        assert info.correction_iterations > 0
        assert gap == pytest.approx(-0.1 * 0.2 * 2e-3, abs=1e-9)
    else:
        assert info.correction_iterations == 0
        assert gap == pytest.approx(-1e-3, abs=1e-12)


def test_the_rule_is_a_setting_whose_default_keeps_the_slops_in_d():
    config = load_config_dict(pinacoids())
    assert config.overlap.slop_scale == "largest" and not step_parameters(config).slops_by_pair
    assert step_parameters(load_config_dict(pinacoids(overlap={"slop_scale": "pair"}))).slops_by_pair
