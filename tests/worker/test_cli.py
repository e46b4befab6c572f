from worker.training.cli import main


def test_cli_names_the_bad_field(tmp_path, capsys):
    assert main(["train", "--out", str(tmp_path), "--models", "svm,nope"]) == 2
    assert "--models" in capsys.readouterr().err
    assert main(["train", "--out", str(tmp_path), "--folds", "1"]) == 2
    assert "--folds" in capsys.readouterr().err
    assert main(["--urfd-dir", str(tmp_path), "train-default", "--out", str(tmp_path / "m")]) == 2
    assert "VIGIL_URFD_DIR" in capsys.readouterr().err
    assert not (tmp_path / "m").exists()
