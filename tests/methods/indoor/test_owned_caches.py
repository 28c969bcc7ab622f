"""The indoor method's derived data lives on the object it describes, never in a module dict keyed
by ``id()`` (an id is reused once its object is collected, so such a key can alias a new object).

Gain arrays and the sensing memo's key are kept on the gain set (``IndoorGains``), footprint arrays
on the obstacle tree (``ObstacleTree``) or the engine's environment.
"""

from __future__ import annotations

import gc
import weakref
from dataclasses import replace

import numpy as np
from shapely import STRtree
from shapely.geometry import LineString, box

from swarmscene import api
from swarmscene.core.environment import footprint_arrays
from swarmscene.methods.indoor import control, sensing, shared
from swarmscene.methods.indoor.control import AVOIDANCE_GAINS, FORMATION_GAINS, TABLE_5_1, IndoorGains
from swarmscene.methods.indoor.sensing import ObstacleTree, kernel_obstacles, obstacle_tree

QUIET = ["output.progress=off", "output.summary=false", "output.trajectory=false"]


def test_gain_arrays_follow_each_gain_set_even_when_an_id_is_reused():
    # Build and drop gain sets one after another: CPython hands a freed id to the next object, so
    # an id()-keyed cache would return the previous set's array here.
    ids = set()
    for k in range(1, 40):
        g = replace(TABLE_5_1, K_con=float(k), K_col=float(2 * k))
        ids.add(id(g))
        assert g.formation_kernel_gains[FORMATION_GAINS.index("K_con")] == k
        assert g.avoidance_kernel_gains[AVOIDANCE_GAINS.index("K_col")] == 2 * k
        np.testing.assert_array_equal(g.formation_kernel_gains, g.kernel_gains(FORMATION_GAINS))
        del g
    assert len(ids) < 39  # ids were reused, so the check above was a real one


def test_two_gain_sets_do_not_share_arrays_or_keys():
    a, b = IndoorGains(d_n=1.0, K_com=0.1), IndoorGains(d_n=1.5, K_com=0.2)
    assert a.formation_kernel_gains is not b.formation_kernel_gains
    assert not np.array_equal(a.formation_kernel_gains, b.formation_kernel_gains)
    assert a.formation_kernel_gains is a.formation_kernel_gains  # built once per set
    assert dict(a.snapshot_key)["d_n"] == 1.0 and dict(b.snapshot_key)["d_n"] == 1.5
    assert a.sensing_reach == min(a.l_o, a.d_s)
    assert a == IndoorGains(d_n=1.0, K_com=0.1)  # the kept arrays are not fields: equality holds


def test_no_module_keeps_a_gain_set_or_an_obstacle_set_alive():
    g = replace(TABLE_5_1, K_led=0.07)
    _ = g.formation_kernel_gains, g.avoidance_kernel_gains, g.snapshot_key
    tree = obstacle_tree([box(0, 0, 1, 1)])
    kernel_obstacles(tree)
    refs = [weakref.ref(g), weakref.ref(tree)]
    del g, tree
    gc.collect()
    assert [r() for r in refs] == [None, None]
    for module in (control, sensing, shared):  # and no id-keyed dict is left at module level
        assert not [k for k, v in vars(module).items() if isinstance(v, dict) and k.isupper()
                    and any(isinstance(key, (int, tuple)) for key in v)], module.__name__


def test_two_obstacle_trees_keep_their_own_footprints():
    walls_a = [LineString([(0, 0), (4, 0)])]
    walls_b = [box(1, 1, 2, 3), LineString([(5, 0), (5, 5)])]
    a, b = obstacle_tree(walls_a), obstacle_tree(walls_b)
    assert isinstance(a, ObstacleTree) and isinstance(b, ObstacleTree)
    fa, fb = kernel_obstacles(a), kernel_obstacles(b)
    assert kernel_obstacles(a) is fa  # converted once for the set
    for got, want in ((fa, footprint_arrays(a.geometries)), (fb, footprint_arrays(b.geometries))):
        for x, y in zip(got, want, strict=True):
            np.testing.assert_array_equal(x, y)
    assert len(fa[0]) != len(fb[0])
    plain = STRtree(np.asarray(walls_b, dtype=object))  # a caller's own tree: converted per call
    for x, y in zip(kernel_obstacles(plain), fb, strict=True):
        np.testing.assert_array_equal(x, y)


def test_two_indoor_runs_keep_their_own_gains():
    one = api.build(["scenario=indoor_corridor", "formation.K_com=0.1", *QUIET])
    two = api.build(["scenario=indoor_corridor", "formation.K_com=0.05", *QUIET])
    ga, gb = one.formation.gains, two.formation.gains
    k = FORMATION_GAINS.index("K_com")
    assert ga.formation_kernel_gains[k] == 0.1 and gb.formation_kernel_gains[k] == 0.05
    one.step(), two.step()
    assert ga.formation_kernel_gains[k] == 0.1 and gb.formation_kernel_gains[k] == 0.05
