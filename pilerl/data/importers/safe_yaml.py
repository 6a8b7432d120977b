"""A YAML loader for mapping files: plain data only, no duplicate keys, bounded size.

``yaml.safe_load`` builds no objects, but it still lets a later duplicate key replace an
earlier one silently (a second ``time:`` block replaced a time column with a fixed rate)
and it expands aliases without limit (a 1 KB "billion laughs" file held 2 GB and ran for
minutes once walked). This loader refuses both, names the line, and refuses files and
documents over sane sizes before building them.
"""

from __future__ import annotations

import codecs
from pathlib import Path

import yaml

MAX_BYTES = 1 << 20  # 1 MiB: a mapping is a few KB
MAX_ALIASES = 100  # alias uses (``*name``) per document
MAX_NODES = 100_000  # nodes of the document with every alias expanded


class YamlError(ValueError):
    """The text is not an acceptable YAML mapping file; the message says where and why."""


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that counts aliases and rejects duplicate mapping keys."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self.alias_uses = 0

    def compose_node(self, parent, index):  # noqa: ANN001 - PyYAML's signature
        if self.check_event(yaml.AliasEvent):
            self.alias_uses += 1
            if self.alias_uses > MAX_ALIASES:
                mark = self.peek_event().start_mark
                raise YamlError(
                    f"line {mark.line + 1}: more than {MAX_ALIASES} aliases (*name); "
                    "a mapping needs none"
                )
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):  # noqa: ANN001 - PyYAML's signature
        if isinstance(node, yaml.MappingNode):
            seen: dict[object, int] = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    continue  # PyYAML itself reports unhashable keys
                line = key_node.start_mark.line + 1
                if key in seen:
                    raise YamlError(
                        f"line {line}: duplicate key {key!r} (first at line {seen[key]}); "
                        "the later one would silently replace it"
                    )
                seen[key] = line
        return super().construct_mapping(node, deep=deep)


def _expanded_size(node: yaml.Node, memo: dict[int, int]) -> int:
    """Number of nodes once every alias is expanded (memoised: shared nodes count once
    each time they are reached, without walking them again)."""
    if id(node) in memo:
        return memo[id(node)]
    memo[id(node)] = 1  # a recursive alias counts once instead of looping
    if isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(child, memo) for child in node.value)
    elif isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
    else:
        size = 1
    memo[id(node)] = min(size, MAX_NODES + 1)
    return memo[id(node)]


def decode_text(data: bytes) -> str:
    """UTF-8 (with or without a BOM) or UTF-16/32 with a BOM; anything else is refused."""
    for bom, encoding in (
        (codecs.BOM_UTF32_LE, "utf-32"),
        (codecs.BOM_UTF32_BE, "utf-32"),
        (codecs.BOM_UTF8, "utf-8-sig"),
        (codecs.BOM_UTF16_LE, "utf-16"),
        (codecs.BOM_UTF16_BE, "utf-16"),
    ):
        if data.startswith(bom):
            try:
                return data.decode(encoding)
            except UnicodeDecodeError as error:
                raise YamlError(f"invalid {encoding} text at byte {error.start}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        raise YamlError(
            f"line {line}: not UTF-8 text (byte 0x{data[error.start]:02x} at offset "
            f"{error.start}); save the file as UTF-8"
        ) from None


def load_yaml_text(text: str) -> object:
    """Plain data from one YAML document; ``YamlError`` on anything this module refuses."""
    if len(text.encode("utf-8", "surrogatepass")) > MAX_BYTES:
        raise YamlError(f"larger than {MAX_BYTES} bytes; a mapping is a few KB")
    loader = _StrictLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        size = _expanded_size(node, {})
        if size > MAX_NODES:
            raise YamlError(f"more than {MAX_NODES} values once aliases are expanded")
        return loader.construct_document(node)
    except yaml.YAMLError as error:
        raise YamlError(str(error).replace("\n", " ")) from None
    finally:
        loader.dispose()


def load_yaml_file(path: str | Path) -> object:
    """``load_yaml_text`` of a file, decoded by ``decode_text``; size checked before reading."""
    path = Path(path)
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise YamlError(f"{size} bytes, larger than {MAX_BYTES}; a mapping is a few KB")
    return load_yaml_text(decode_text(path.read_bytes()))
