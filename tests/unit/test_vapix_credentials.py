"""Camera credentials from the environment or a file (``vapix/credentials.py``): never from a parameter, never
logged; a file others can read is reported by name and mode only."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.vapix.credentials import load_credentials

pytestmark = pytest.mark.unit


@pytest.fixture(autouse=True)
def _no_credentials_in_env(monkeypatch):
    for name in ("AXIS_USERNAME", "AXIS_PASSWORD", "AXIS_PASSWORD_FILE"):
        monkeypatch.delenv(name, raising=False)


def test_anonymous_without_anything():
    assert load_credentials() == (None, None)


def test_environment_and_root_as_the_default_user(monkeypatch):
    monkeypatch.setenv("AXIS_PASSWORD", "s3cret")
    assert load_credentials() == ("root", "s3cret")
    monkeypatch.setenv("AXIS_USERNAME", "operator")
    assert load_credentials() == ("operator", "s3cret")


def test_a_file_wins_and_an_open_one_is_reported_once_without_its_content(tmp_path, monkeypatch):
    monkeypatch.setenv("AXIS_PASSWORD", "from-env")
    private = tmp_path / "private.txt"
    private.write_text("viewer:pa:ss\nignored\n", encoding="utf-8")
    private.chmod(0o600)
    said: list[str] = []
    assert load_credentials(str(private), warn=said.append) == ("viewer", "pa:ss")
    assert said == []
    shared = tmp_path / "shared.txt"
    shared.write_text("viewer:topsecret\n", encoding="utf-8")
    shared.chmod(0o644)
    assert load_credentials(str(shared), warn=said.append) == ("viewer", "topsecret")
    assert load_credentials(str(shared), warn=said.append) == ("viewer", "topsecret")
    assert len(said) == 1
    assert "644" in said[0]
    assert "chmod 600" in said[0]
    assert "topsecret" not in said[0]
    monkeypatch.setenv("AXIS_PASSWORD_FILE", str(private))
    assert load_credentials() == ("viewer", "pa:ss")


def test_a_file_without_user_and_password_is_refused(tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("just-a-password\n", encoding="utf-8")
    bad.chmod(0o600)
    with pytest.raises(ValueError, match="user:password"):
        load_credentials(str(bad))
    with pytest.raises(FileNotFoundError):
        load_credentials(str(tmp_path / "missing.txt"))
