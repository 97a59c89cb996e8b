"""Launch files are well-formed and every arg they use is declared."""
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

LAUNCH = sorted(Path("launch").glob("*.launch")) + sorted(Path("test/ros").glob("*.test"))


@pytest.mark.parametrize("path", LAUNCH, ids=lambda p: p.name)
def test_launch_file_parses_and_declares_its_args(path):
    root = ET.parse(path).getroot()
    assert root.tag == "launch"
    declared = {a.get("name") for a in root.iter("arg")}
    used = set(re.findall(r"\$\(arg ([\w]+)\)", path.read_text()))
    used |= set(re.findall(r"arg\('([\w]+)'\)", path.read_text()))
    assert used <= declared, f"undeclared args: {used - declared}"
    for node in root.iter("node"):
        if node.get("pkg") == "assign5":
            assert Path("src", node.get("type")).exists(), node.get("type")
