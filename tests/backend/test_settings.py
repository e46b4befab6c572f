import stat

from backend.settings import Settings


def test_without_a_configured_key_one_random_key_is_generated_and_kept(tmp_path, monkeypatch):
    monkeypatch.delenv("VIGIL_SECRET_KEY", raising=False)
    key_file = tmp_path / "var" / "secret_key"
    first = Settings(secret_key_file=key_file).secret_key
    assert len(first) >= 48
    assert stat.S_IMODE(key_file.stat().st_mode) == 0o600
    assert Settings(secret_key_file=key_file).secret_key == first
    assert Settings(secret_key_file=tmp_path / "other").secret_key != first


def test_a_configured_key_wins_and_no_file_is_written(tmp_path):
    key_file = tmp_path / "secret_key"
    assert Settings(secret_key="configured", secret_key_file=key_file).secret_key == "configured"
    assert not key_file.exists()
