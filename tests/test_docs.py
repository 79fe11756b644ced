"""The docs match the code: the API reference lists every public name, the README points in."""

import re
from pathlib import Path

import nextage_qp
from nextage_qp import api, errors

ROOT = Path(__file__).resolve().parents[1]


def test_api_reference_covers_every_public_name() -> None:
    text = (ROOT / "docs" / "api.md").read_text()
    listed = set(re.findall(r"[A-Za-z_]+", " ".join(re.findall(r"members: \[([^\]]*)\]", text))))
    assert set(api.__all__) <= listed, set(api.__all__) - listed
    assert "::: nextage_qp.errors" in text  # every error class, the whole module
    exported = set(nextage_qp.__all__)
    documented = listed | {n for n in dir(errors) if isinstance(getattr(errors, n), type)}
    documented |= {name for name in ("Robot", "SceneOverrides") if re.search(rf"::: nextage_qp\.[\w.]+\.{name}\b", text)}
    missing = exported - documented
    assert not missing, missing


def test_every_docs_page_is_in_the_site_and_every_example_is_listed() -> None:
    nav = (ROOT / "mkdocs.yml").read_text()
    for page in (ROOT / "docs").glob("*.md"):
        assert page.name in nav, page.name
    listed = (ROOT / "docs" / "examples.md").read_text()
    for script in (ROOT / "examples").glob("*.py"):
        assert f"examples/{script.name}" in listed, script.name


def test_readme_leads_to_the_docs() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    first_screen = "\n".join(lines[:40])
    assert "pip install" in first_screen and "pytest" in first_screen  # install and test
    assert "| task |" in first_screen or "| task" in first_screen  # the results table
    assert "docs/tasks.md" in first_screen  # write your own task
