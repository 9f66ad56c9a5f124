import numpy as np
from matplotlib.patches import Ellipse

from hrtls.wsn.diagnostics import unlocalized_reasons
from hrtls.wsn.network import corner_seed_network, network_from_positions
from hrtls.wsn.plotting import plot_network
from hrtls.wsn.refine import RefineParams, refine_network
from hrtls.wsn.shadow_edge import shadow_edge_localize
from hrtls.wsn.trilateration import PropagationParams


def _two_parts():
    # three anchors and a trilaterable node near the origin; a separate pair far away; one node
    # with only two localized neighbours (an anchor and the placed node) and no shadow.
    pos = np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 0.1], [0.08, 0.08],
                    [2.0, 2.0], [2.1, 2.0], [0.25, 0.0]])
    anchor = np.array([True, True, True, False, False, False, False])
    return network_from_positions(pos, radius_m=0.2, anchor=anchor)


def test_reasons_split_unreachable_and_under_covered():
    net = _two_parts()
    loc = shadow_edge_localize(net)
    why = unlocalized_reasons(net, loc)
    assert loc.localized[3]
    assert set(why.unreachable.tolist()) == {4, 5}
    assert why.n_unlocalized == int((~loc.localized).sum())
    groups = [set(g.tolist()) for g in (why.unreachable, why.inconsistent, why.under_covered)]
    assert sum(len(g) for g in groups) == len(set().union(*groups))


def test_plot_draws_covariance_ellipses_and_keeps_legend_outside():
    net = corner_seed_network(np.random.default_rng(3), n_nodes=60, radius_m=0.35,
                              range_noise_fraction=0.02)
    loc = shadow_edge_localize(net, params=PropagationParams.for_noise(0.02))
    ref = refine_network(net, loc, params=RefineParams(range_sigma_fraction=0.02))
    placed = loc.localized & ~net.anchor
    assert placed.sum() >= 5
    fig = plot_network(net, loc, covariance_m2=ref.covariance_m2)
    ax = fig.axes[0]
    ellipses = [p for p in ax.patches if isinstance(p, Ellipse)]
    assert len(ellipses) == int(placed.sum())
    legend = ax.get_legend()
    fig.canvas.draw()
    box = legend.get_window_extent()
    assert box.x0 >= ax.get_window_extent().x1 - 1.0
