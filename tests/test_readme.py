"""README's generated sections match the code and the benchmark files they quote."""

import pytest

from scripts import readme


@pytest.mark.parametrize("name", sorted(readme.SECTIONS))
def test_readme_section_matches_its_source(name):
    expected = readme.SECTIONS[name]().strip()
    assert readme.readme_section(name) == expected, (
        f"README's {name} section is stale: run `python -m scripts.readme --write`"
    )


def test_readme_names_the_two_commands():
    text = readme.README.read_text()
    assert "make run" in text and "make test" in text
