"""The documentation: the configuration reference is current and complete; links resolve."""

import dataclasses
from pathlib import Path
import re
import typing
from typing import Optional, Tuple

import pytest
from wet_eha_thermal.config import Config, spec
from wet_eha_thermal.config_doc import config_reference

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / 'README.md', *sorted((ROOT / 'docs').rglob('*.md'))]
# [text](target) and ![alt](target), the target up to a space or the closing parenthesis
LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)[^)]*\)')
FENCE = re.compile(r'^(```|~~~)')


def prose_lines(text):
    """Yield the lines of a Markdown text outside fenced code blocks, inline code removed."""
    fenced = False
    for line in text.splitlines():
        if FENCE.match(line.lstrip()):
            fenced = not fenced
            continue
        if not fenced:
            yield re.sub(r'`[^`]*`', '', line)


def heading_texts(page):
    """Return the heading lines of a page with their inline code kept (for anchors)."""
    fenced, out = False, []
    for line in page.read_text().splitlines():
        if FENCE.match(line.lstrip()):
            fenced = not fenced
        elif not fenced and re.match(r'#{1,6}\s', line):
            out.append(line)
    return out


def page_anchors(page):
    """Return the anchors of a page's headings, code spans counted as their text."""
    seen, out = {}, set()
    for line in heading_texts(page):
        text = re.match(r'#{1,6}\s+(.*?)\s*$', line).group(1)
        slug = re.sub(r'[^\w\- ]', '', text.lower()).replace(' ', '-')
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f'{slug}-{n}')
    return out


def broken_links(page):
    """Return the relative links of a page whose file or heading does not exist."""
    bad = []
    for line in prose_lines(page.read_text()):
        for target in LINK.findall(line):
            if re.match(r'[a-z][a-z0-9+.-]*:', target):      # http:, https:, mailto:
                continue
            path, _, anchor = target.partition('#')
            dest = (page.parent / path).resolve() if path else page
            if not dest.exists():
                bad.append(f'{target}: no file {dest}')
            elif anchor and (dest.suffix != '.md' or anchor not in page_anchors(dest)):
                bad.append(f'{target}: no heading #{anchor} in {dest.name}')
    return bad


def test_configuration_reference_is_generated():
    committed = (ROOT / 'docs' / 'configuration.md').read_text()
    assert committed == config_reference(ROOT / 'config'), (
        'docs/configuration.md is not what the configuration says; regenerate it with '
        '`python -m wet_eha_thermal.config_doc > docs/configuration.md`')


def undocumented(cls, key):
    """Return the dotted keys under dataclass ``cls``, in sections and lists too, without a doc."""
    hints, out = typing.get_type_hints(cls), []
    for f in dataclasses.fields(cls):
        sub = f'{key}.{f.name}'
        if not f.metadata.get('doc'):
            out.append(sub)
        for tp in (hints[f.name], *typing.get_args(hints[f.name])):
            if dataclasses.is_dataclass(tp):
                out += undocumented(tp, sub)
    return out


def test_every_key_is_described():
    # the top-level sections are the page's headings, described by their classes' docstrings
    hints = typing.get_type_hints(Config)
    missing = [k for f in dataclasses.fields(Config)
               for tp in (hints[f.name], *typing.get_args(hints[f.name]))    # Optional[...]
               if dataclasses.is_dataclass(tp) for k in undocumented(tp, f.name)]
    assert missing == [], f'no doc= in wet_eha_thermal/config.py: {", ".join(missing)}'


def test_undocumented_finds_keys_in_subsections():
    @dataclasses.dataclass
    class Part:
        said: float = spec(doc='described')
        unsaid: float = spec()

    @dataclasses.dataclass
    class Whole:
        part: Optional[Part] = spec(doc='an optional section')
        parts: Tuple[Part, ...] = spec()

    assert undocumented(Whole, 'w') == ['w.part.unsaid', 'w.parts', 'w.parts.unsaid']


@pytest.mark.parametrize('page', PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_links_resolve(page):
    assert broken_links(page) == []


def test_link_check_finds_a_broken_link(tmp_path):
    (tmp_path / 'b.md').write_text('# The `b` page\n\n## Same\n\n## Same\n')
    page = tmp_path / 'a.md'
    page.write_text('[ok](b.md#the-b-page) [ok](b.md#same-1) [ok](#here) `[code](x.md)`\n'
                    '# Here\n[missing](c.md) [no heading](b.md#nowhere) [self](#gone)\n'
                    '```\n[in a fence](d.md)\n```\n')
    assert broken_links(page) == [
        f'c.md: no file {tmp_path / "c.md"}', 'b.md#nowhere: no heading #nowhere in b.md',
        '#gone: no heading #gone in a.md']
