"""The user pages read in short sentences (issue #52: under 25 words on average).

The counter, :func:`sentence_lengths`, reads a Markdown page by these rules:

- dropped: fenced code blocks (```` ``` ```` or ``~~~``), indented code blocks, tables
  (lines that start with ``|``), headings (lines that start with ``#``), HTML comments and
  tags, and admonition markers (``!!! note``);
- inline code (`` `scene3d evaluate --pairs 4-5` ``) counts as one word, so a long command
  in a sentence weighs like a name;
- a link keeps its text and loses its target (``[Benchmarks](benchmarks.md#dense)`` is the
  word "Benchmarks"); a bare URL is one word;
- list markers (``-``, ``*``, ``+``, ``1.``) and blockquote markers (``>``) are dropped, and
  each list item starts a new sentence;
- a blank line ends a sentence (a paragraph ends its last one, with or without a full stop);
- within a paragraph, a sentence ends at ``.``, ``!`` or ``?`` (optionally followed by a
  closing bracket or quote) followed by a space or a line end; a decimal point
  (``0.5``) and a file name (``out/cloud.ply``) have none after them and do not end one;
- a word is a run of characters between spaces that holds a letter or a digit.

The average is the words of the page over its sentences.
"""

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
SHORT_PAGES = ["cli.md", "many-views.md", "own-photos.md", "troubleshooting.md", "tutorial.md"]
MAX_AVERAGE_WORDS = 25

_LIST_ITEM = re.compile(r"^\s*(?:[-*+]|\d+[.)])\s+")
_SENTENCE_END = re.compile(r"""(?<=[.!?])[)\]"'”’]*\s+""")


def _prose_lines(text: str) -> list[str]:
    """The page's lines without code blocks, tables, headings and HTML; '' between blocks."""
    lines, fence = [], None
    for line in text.splitlines():
        stripped = line.strip()
        if fence is not None:
            if stripped.startswith(fence):
                fence = None
            lines.append("")
            continue
        if stripped.startswith(("```", "~~~")):
            fence = stripped[:3]
            lines.append("")
            continue
        if (stripped.startswith(("|", "#", "!!!", "<")) or
                (line.startswith("    ") and not _LIST_ITEM.match(line) and
                 (not lines or lines[-1] == ""))):
            lines.append("")
            continue
        lines.append(line)
    return lines


def _inline(text: str) -> str:
    """Inline code as one word, links as their text, HTML comments and tags gone."""
    text = re.sub(r"<!--.*?-->", " ", text, flags=re.S)
    text = re.sub(r"`[^`]*`", "CODE", text)
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)
    text = re.sub(r"!?\[([^\]]*)\]\[[^\]]*\]", r"\1", text)
    text = re.sub(r"https?://\S+", "URL", text)
    return re.sub(r"<[^>]+>", " ", text)


def sentence_lengths(text: str) -> list[int]:
    """Words per sentence of a Markdown page (the rules are in this module's docstring).

    Parameters
    ----------
    text : str
        The page's Markdown.

    Returns
    -------
    list of int
        One count per sentence, in the page's order; sentences without a word are left out.
    """
    blocks, current = [], []
    for line in _prose_lines(text):
        line = re.sub(r"^\s*>\s?", "", line)
        if not line.strip():
            blocks.append(" ".join(current))
            current = []
        elif _LIST_ITEM.match(line):
            blocks.append(" ".join(current))
            current = [_LIST_ITEM.sub("", line)]
        else:
            current.append(line.strip())
    blocks.append(" ".join(current))
    counts = []
    for block in blocks:
        for sentence in _SENTENCE_END.split(_inline(block)):
            words = [w for w in sentence.split() if re.search(r"\w", w)]
            if words:
                counts.append(len(words))
    return counts


def average_sentence_words(path: Path) -> float:
    counts = sentence_lengths(path.read_text(encoding="utf-8"))
    return sum(counts) / len(counts)


def test_the_counter_on_a_page_with_every_rule():
    page = "\n".join([
        "# A heading of several words that is left out",
        "",
        "One two three. Four five six seven eight nine? Ten eleven 0.5 words,",
        "across a line break! See [the many words of a link](a.md#target) in "
        "`scene3d evaluate --pairs 4-5` (here.) Then",
        "",
        "- a list item",
        "- another item. With two sentences",
        "1. numbered",
        "",
        "| a | table | row |",
        "```",
        "code. more code. even more",
        "```",
        "    indented code. block",
        "",
        "> a quote.",
    ])
    assert sentence_lengths(page) == [3, 6, 8, 10, 1, 3, 2, 3, 1, 2]


@pytest.mark.parametrize("page", SHORT_PAGES)
def test_user_pages_average_under_25_words_a_sentence(page):
    average = average_sentence_words(DOCS / page)
    assert average < MAX_AVERAGE_WORDS, f"{page}: {average:.1f} words a sentence"
