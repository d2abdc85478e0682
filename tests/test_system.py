"""Plants of eqs. (18)-(20): validation, evaluation of couplings, serialisation."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from nrobust import Hyperbolic2x2, ParameterError, TransportSystem


def paper_system() -> Hyperbolic2x2:
    return Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)


def test_derived_quantities():
    system = Hyperbolic2x2(lam=2.0, mu=0.5, sigma_pm=1.0, sigma_mp=-0.3, q=-1.5, rho=0.4)
    assert system.tau == pytest.approx(2.5, rel=1e-13, abs=1e-14)
    assert system.rho_q == pytest.approx(-0.6, rel=1e-13, abs=1e-14)
    assert system.constant_couplings and not system.uncoupled


def test_frozen_and_repr():
    system = paper_system()
    with pytest.raises(dataclasses.FrozenInstanceError):
        system.lam = 2.0  # type: ignore[misc]
    assert repr(system) == "Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)"
    varying = Hyperbolic2x2(1.0, 2.0, np.cos, 0.5, 1.0, 0.2)
    assert "sigma_pm=<function cos>" in repr(varying)


def test_to_dict_is_json_and_tabulates_callables():
    system = Hyperbolic2x2(1.0, 2.0, lambda x: 1.0 + x, 0.5, 1.0, 0.2)
    data = json.loads(json.dumps(system.to_dict()))
    assert data["type"] == "Hyperbolic2x2"
    assert data["sigma_mp"] == 0.5
    assert data["sigma_pm"]["values"][-1] == pytest.approx(2.0, rel=1e-13, abs=1e-14)
    assert data["tau"] == pytest.approx(1.5, rel=1e-13, abs=1e-14)


def test_couplings_evaluate_on_arrays():
    x = np.linspace(0.0, 1.0, 7).reshape(7, 1)
    system = Hyperbolic2x2(1.0, 2.0, lambda x: 1.0 + x**2, 0.25, 1.0, 0.2)
    np.testing.assert_allclose(system.sigma_pm_at(x), 1.0 + x**2, rtol=1e-15, atol=0)
    np.testing.assert_allclose(system.sigma_mp_at(x), np.full((7, 1), 0.25), rtol=1e-15, atol=0)


def test_scalar_only_callable_is_wrapped():
    system = Hyperbolic2x2(1.0, 2.0, math.sin, lambda x: 2.0, 1.0, 0.2)
    x = np.array([0.1, 0.5, 0.9])
    np.testing.assert_allclose(system.sigma_pm_at(x), np.sin(x), rtol=1e-15, atol=0)
    np.testing.assert_allclose(system.sigma_mp_at(x), [2.0, 2.0, 2.0], rtol=1e-15, atol=0)
    assert not system.constant_couplings


def test_transport_system_is_uncoupled_hyperbolic():
    system = TransportSystem(lam=1.0, mu=2.0, q=0.5, rho=1.5)
    assert isinstance(system, Hyperbolic2x2)
    assert system.uncoupled
    assert system.sigma_pm == 0.0 and system.sigma_mp == 0.0
    assert system.tau == pytest.approx(1.5, rel=1e-13, abs=1e-14)
    assert system.rho_q == pytest.approx(0.75, rel=1e-13, abs=1e-14)
    assert repr(system) == "TransportSystem(lam=1.0, mu=2.0, q=0.5, rho=1.5)"
    np.testing.assert_array_equal(system.sigma_pm_at([0.0, 1.0]), [0.0, 0.0])


@pytest.mark.parametrize(
    "change, name",
    [
        ({"lam": 0.0}, "lam"),
        ({"lam": -1.0}, "lam"),
        ({"mu": 0.0}, "mu"),
        ({"mu": float("inf")}, "mu"),
        ({"q": 0.0}, "q"),
        ({"q": float("nan")}, "q"),
        ({"rho": float("nan")}, "rho"),
        ({"rho": "0.5x"}, "rho"),
        ({"sigma_pm": "abc"}, "sigma_pm"),
        ({"sigma_pm": [1.0, 2.0]}, "sigma_pm"),
        ({"sigma_pm": True}, "sigma_pm"),
        ({"sigma_mp": float("inf")}, "sigma_mp"),
        ({"sigma_mp": lambda x: 1.0 / (x - 0.5)}, "sigma_mp"),
        ({"sigma_mp": lambda x: np.log(x - 0.5)}, "sigma_mp"),
        ({"sigma_pm": lambda x: 1j * x}, "sigma_pm"),
        ({"sigma_pm": lambda x: "text"}, "sigma_pm"),
    ],
)
def test_invalid_data_raise_parameter_error(change, name):
    kwargs = {"lam": 1.0, "mu": 1.0, "sigma_pm": 1.0, "sigma_mp": 1.0, "q": 1.0, "rho": 0.85}
    kwargs.update(change)
    with pytest.raises(ParameterError) as info:
        Hyperbolic2x2(**kwargs)
    assert info.value.name == name
    assert isinstance(info.value, ValueError)


def test_transport_system_validates():
    with pytest.raises(ParameterError):
        TransportSystem(lam=1.0, mu=1.0, q=0.0, rho=1.0)


def _module_level_coupling(x):
    return 1.0 + 0.5 * x


def test_systems_pickle_for_worker_processes():
    """Sweeps and charts send systems to other processes: they must pickle."""
    import pickle

    for system in (
        Hyperbolic2x2(1.0, 2.0, 0.5, 0.25, 0.8, 0.5),
        Hyperbolic2x2(1.0, 2.0, _module_level_coupling, 0.25, 0.8, 0.5),
        TransportSystem(1.0, 1.0, 1.0, 0.85),
    ):
        again = pickle.loads(pickle.dumps(system))
        x = np.linspace(0.0, 1.0, 5)
        assert again == system
        np.testing.assert_array_equal(again.sigma_pm_at(x), system.sigma_pm_at(x))
