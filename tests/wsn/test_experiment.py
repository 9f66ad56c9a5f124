from hrtls.wsn.experiment import format_table, loose_study, noise_study, tight_study


def test_loose_study_connected_networks_complete():
    s = loose_study(n_networks=40, seed=3)
    rows = {r.group: r for r in s.rows}
    assert rows["all"].networks == 40
    assert rows["all"].sela >= rows["all"].tla
    assert rows["all"].sela_planner >= rows["all"].sela
    assert rows["all"].max_error_over_rho < 1e-9
    if "connected" in rows:
        assert rows["connected"].complete == 1.0
        assert rows["connected"].sela_planner == 1.0
    text = format_table(s.rows)
    assert "sela_planner" in text and len(text.splitlines()) == len(s.rows) + 2


def test_tight_study_small():
    t = tight_study(n_networks=4, n_nodes=10, side_m=0.5, seed=2)
    assert t.rows[0].group == "all"
    for r in t.rows:
        if r.group != "disconnected beyond d_r":
            assert r.complete == 1.0
        assert r.rmse_over_rho < 0.2


def test_noise_study_small():
    z = noise_study(n_networks=3, max_gdops=(2.5,), with_planner=False)
    assert len(z.rows) == 1
    assert 0 < z.rows[0].rmse_refined_over_rho < 0.2
