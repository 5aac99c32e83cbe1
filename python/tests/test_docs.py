"""docs/python.md's code runs as written: its ``python`` blocks, in order, in one namespace."""

import re

from conftest import ROOT


def test_the_examples_of_docs_python_md_run(cli, tmp_path, monkeypatch, capsys):
    text = (ROOT / "docs" / "python.md").read_text()
    blocks = re.findall(r"^```python\n(.*?)^```$", text, flags=re.M | re.S)
    assert len(blocks) >= 5
    monkeypatch.chdir(tmp_path)
    # The examples run from the repository's root, where its test captures are.
    (tmp_path / "crates").symlink_to(ROOT / "crates")
    monkeypatch.setenv("ROBOKEY_BIN", str(cli.binary))
    namespace: dict = {}
    for i, block in enumerate(blocks):
        exec(compile(block, f"docs/python.md, block {i + 1}", "exec"), namespace)
    printed = capsys.readouterr().out
    assert "`protocol.delta_v` = 0.0 is not allowed" in printed
    assert "codewords sent     340" in printed
    assert "camera" in printed and "secret_bits" in printed
    assert "robokey frames of sessions" in printed and "settled" in printed
    assert "identify: 40 steps decided, key 10 bits" in printed
    assert "folder" in namespace and (namespace["folder"] / "trace.csv").exists()
