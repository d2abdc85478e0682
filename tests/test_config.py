"""The TOML reader of the input files, on every supported Python."""

import sys

import pytest

from nrobust import config
from nrobust.errors import ParameterError


def test_toml_reader_matches_the_python_version():
    # the standard library has tomllib from 3.11 on; 3.10 needs tomli (CI runs tests/test_cli.py on 3.10 too)
    expected = "tomllib" if sys.version_info >= (3, 11) else "tomli"
    assert config.tomllib.__name__ == expected


def test_load_toml_reads_and_names_bad_files(tmp_path):
    good = tmp_path / "a.toml"
    good.write_text('[system]\ntype = "TransportSystem"\nrho = 0.5\n', encoding="utf-8")
    assert config.load_toml(good) == {"system": {"type": "TransportSystem", "rho": 0.5}}
    bad = tmp_path / "b.toml"
    bad.write_text("[system\n", encoding="utf-8")
    with pytest.raises(ParameterError, match="valid TOML"):
        config.load_toml(bad)
    with pytest.raises(ParameterError, match="existing"):
        config.load_toml(tmp_path / "missing.toml")


def test_registries_build_what_they_name():
    for name, cls in config.SYSTEM_TYPES.items():
        assert cls.__name__ == name
    for name, cls in config.CONTROLLER_TYPES.items():
        assert cls.__name__ == name
