"""The example data shipped with the apps is what its generator makes."""

from pathlib import Path

from mmlearn.apps.examples import make_examples

SHIPPED = Path(__file__).resolve().parents[1] / "apps" / "examples" / "two_drawer_cabinet.csv"


def test_make_examples_reproduces_the_shipped_csv(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(make_examples, "HERE", tmp_path)
    make_examples.main()
    assert "two_drawer_cabinet.csv" in capsys.readouterr().out
    assert (tmp_path / "two_drawer_cabinet.csv").read_text() == SHIPPED.read_text()
