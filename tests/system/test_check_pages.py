"""docs/check_pages.py, the browser check CI runs on the docs and a report: it passes a page
whose image loads and fails a broken image and a blank page (a check that cannot fail
would prove nothing). Needs a Chrome-like browser (Debian's chromium); skipped without."""

from __future__ import annotations

import importlib.util
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(
    not any(shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome")),
    reason="no Chrome-like browser (apt-get install chromium)")


@pytest.fixture(scope="module")
def check_pages():
    spec = importlib.util.spec_from_file_location("check_pages", ROOT / "docs" / "check_pages.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["check_pages"] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = tmp_path_factory.mktemp("site")
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    fig.savefig(d / "fig.png")
    plt.close(fig)
    text = "<p>" + "a page with words on it " * 20 + "</p>"
    (d / "good.html").write_text(f"<html><body>{text}<img src='fig.png'></body></html>")
    (d / "broken.html").write_text(f"<html><body>{text}<img src='nope.png'></body></html>")
    (d / "blank.html").write_text("<html><body><div></div></body></html>")
    (d / "sub").mkdir()
    (d / "sub" / "page.html").write_text(f"<html><body>{text}<img src='../fig.png'></body>"
                                         "</html>")
    return d


def test_a_page_that_renders_passes(check_pages, site):
    res = check_pages.check_page(site / "good.html", check_pages.find_browser())
    assert res.ok, res.reason
    assert res.images == 1 and res.text >= 200


def test_a_broken_image_fails(check_pages, site):
    res = check_pages.check_page(site / "broken.html", check_pages.find_browser())
    assert not res.ok and "nope.png" in res.reason


def test_a_blank_page_fails(check_pages, site):
    res = check_pages.check_page(site / "blank.html", check_pages.find_browser())
    assert not res.ok and "blank" in res.reason


def test_a_missing_file_fails_and_the_command_exits_1(check_pages, site, capsys):
    assert check_pages.main([str(site / "absent.html")]) == 1
    assert "no such file" in capsys.readouterr().out


def test_a_page_linking_above_its_folder_needs_the_sites_root(check_pages, site):
    """A page of a site (as a Sphinx build's) loads its images from above its folder: with
    the site's root served it passes, with only its folder it fails."""
    browser = check_pages.find_browser()
    assert check_pages.check_page(site / "sub" / "page.html", browser, site=site).ok
    alone = check_pages.check_page(site / "sub" / "page.html", browser)
    assert not alone.ok and "fig.png" in alone.reason
