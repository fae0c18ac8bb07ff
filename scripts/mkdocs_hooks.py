"""mkdocs hooks (mkdocs.yml ``hooks:``): what the docs pages take from the code when the site is built.

- ``{{ numbers.<run>.<name> }}`` becomes that number of ``docs/numbers.json`` (made from runs by
  ``scripts/doc_numbers.py``, checked against reruns by ``tests/test_numbers.py``), printed as its
  entry says; a name the file does not hold fails the build, naming the page and the name.
- ``<!-- config-options -->`` becomes the option tables of every ``conf/`` group, generated from
  ``conf/`` and the dataclasses (``scripts/config_reference.py``).
"""

from __future__ import annotations

import importlib.util
import re
import sys
from functools import lru_cache
from pathlib import Path

from mkdocs.exceptions import PluginError

ROOT = Path(__file__).resolve().parents[1]
PLACEHOLDER = re.compile(r"\{\{\s*numbers\.([\w.]+)\s*\}\}")
OPTIONS_MARKER = "<!-- config-options -->"


def _script(name: str):
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))  # decrun from this checkout
    spec = importlib.util.spec_from_file_location(f"decrun_docs_{name}", ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


@lru_cache(maxsize=None)
def _numbers():
    module = _script("doc_numbers")
    return module, module.load()


@lru_cache(maxsize=None)
def _options() -> str:
    return _script("config_reference").reference()


def fill_numbers(markdown: str, where: str) -> str:
    """``markdown`` with every ``{{ numbers.<name> }}`` replaced by its printed value."""
    module, numbers = _numbers()

    def value(match: re.Match) -> str:
        name = match.group(1)
        if name not in numbers:
            raise PluginError(f"{where}: {{{{ numbers.{name} }}}} is not in docs/numbers.json; "
                              f"add its run to scripts/doc_numbers.py and run python scripts/doc_numbers.py")
        return module.render(numbers[name])

    return PLACEHOLDER.sub(value, markdown)


def on_page_markdown(markdown: str, page, config, files) -> str:
    where = f"docs/{page.file.src_path}"
    if OPTIONS_MARKER in markdown:
        markdown = markdown.replace(OPTIONS_MARKER, _options())
    return fill_numbers(markdown, where)
