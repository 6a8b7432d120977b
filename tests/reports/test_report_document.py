"""The report document: the same blocks as Markdown and as HTML."""

from __future__ import annotations

from pilerl.reports.document import Report, inline_html


def test_html_renders_markdown_inline_marks_and_escapes_the_rest():
    assert inline_html("run `recipes/evaluate.py checkpoint=<run>`") == (
        "run <code>recipes/evaluate.py checkpoint=&lt;run&gt;</code>"
    )
    assert inline_html("[summer.mp4](videos/summer.mp4)") == (
        '<a href="videos/summer.mp4">summer.mp4</a>'
    )
    assert inline_html("**holds** and *in part*") == ("<strong>holds</strong> and <em>in part</em>")
    assert inline_html("2*3*4 <b>") == "2*3*4 &lt;b&gt;"  # products are not emphasis
    assert inline_html("`a*b*c`") == "<code>a*b*c</code>"  # nothing is parsed inside code


def test_the_same_blocks_give_markdown_and_html(tmp_path):
    report = Report("R & D")
    report.heading("Setup").paragraph("with `p_t`").bullets(["[v](v.mp4)"])
    report.table(["cell", "rate"], [["`winter`", "50%"]]).image("a.png", "a *plot*")
    markdown, page = report.write(tmp_path)
    assert "with `p_t`" in markdown.read_text()
    text = page.read_text()
    assert "<title>R &amp; D</title>" in text
    assert "<p>with <code>p_t</code></p>" in text
    assert '<li><a href="v.mp4">v</a></li>' in text
    assert "<td><code>winter</code></td>" in text
    assert '<img src="a.png" alt="a *plot*">' in text and "<em>plot</em>" in text
