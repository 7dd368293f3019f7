"""`gelenk.mass_matrix` (M alone, in body frames) gives `gelenk.crba`'s M, fills `data.mass_matrix`,
and refuses bad q with the same errors."""

import numpy as np
import pytest

import gelenk


@pytest.mark.parametrize("urdf, floating", [("models/ur5_robot.urdf", False), ("models/solo12.urdf", True)])
def test_mass_matrix_equals_crba(repo, urdf, floating):
    model = gelenk.load_urdf(repo / urdf, floating=floating)
    data, other = gelenk.Data(model), gelenk.Data(model)
    for seed in range(5):
        q = model.random_configuration(seed)
        world = gelenk.crba(model, data, q)
        local = gelenk.mass_matrix(model, other, q)
        assert local.shape == (model.nv, model.nv)
        assert np.array_equal(local, local.T)
        assert np.max(np.abs(local - world)) <= 1e-12 * np.max(np.abs(world))
        assert np.array_equal(other.mass_matrix, local)


def test_bad_q_is_refused_as_by_crba(repo):
    model = gelenk.load_urdf(repo / "models/ur5_robot.urdf")
    data = gelenk.Data(model)
    q = model.neutral()
    with pytest.raises(ValueError, match=r"^q: expected 6 entries, got 5$"):
        gelenk.mass_matrix(model, data, q[:5])
    q[2] = np.nan
    with pytest.raises(ValueError, match=r"^q\[2\] \(joint `elbow_joint`\) is not finite$"):
        gelenk.mass_matrix(model, data, q)
