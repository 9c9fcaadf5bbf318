"""Every YAML file of the project, and the JSON schema fragment (JSON is YAML), loads with unique keys (PyYAML would
silently keep the last duplicate)."""

from pathlib import Path

import pytest
import yaml

from vesicle_core.io import safe_load_unique

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted(p for d in ("config", "workflow") for glob in ("*.y*ml", "*.json") for p in (ROOT / d).rglob(glob))


def test_there_are_yaml_files():
    assert len(FILES) >= 5


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_duplicate_keys(path):
    with open(path) as fh:
        safe_load_unique(fh)


def test_duplicate_key_is_an_error_naming_the_key(tmp_path):
    with pytest.raises(yaml.YAMLError, match="duplicate keys \\['N'\\]"):
        safe_load_unique("N: 64\nL: 5.0\nN: 128\n")
    assert safe_load_unique("a: {b: 1}\nc: [1, 2]\n") == {"a": {"b": 1}, "c": [1, 2]}


def test_run_parameter_file_with_a_repeated_key_is_refused(tmp_path):
    from vesicle_core.errors import ConfigError
    from vesicle_core.model.run_config import load_config

    p = tmp_path / "run.yaml"
    p.write_text("N: 64\nchi: 10.0\nN: 128\n")
    with pytest.raises(ConfigError, match="duplicate keys"):
        load_config(p)
