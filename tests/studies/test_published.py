"""The published setting is data the command line and the examples share: ``rbbench
nitsche-table``'s defaults are it, and its overrides load as a valid scene."""

from __future__ import annotations

from rbbench.cli import build_parser
from rbbench.scene.loading import load_scene
from rbbench.studies.nitsche_eac import published_overrides
from rbbench.studies.published import PUBLISHED_EAC, PUBLISHED_H, PUBLISHED_SETTING


def test_nitsche_table_defaults_are_the_published_setting():
    args = build_parser().parse_args(["nitsche-table"])
    assert {"load.displacement": args.load, "discretization.degree": args.degree,
            "discretization.quadrature": args.quadrature,
            "discretization.normals": args.normals,
            "discretization.contact_integration": args.integration} == PUBLISHED_SETTING
    assert [1e-3 * h for h in args.h] == list(PUBLISHED_H)
    assert sorted(args.mu) == sorted(PUBLISHED_EAC)


def test_published_overrides_load_and_take_changes():
    scene = load_scene("hertz_halfdisks", overrides=published_overrides(discretization__degree=1))
    disc = scene.data["discretization"]
    assert disc["degree"] == 1 and disc["normals"] == "smooth"
    assert disc["contact_integration"] == "segmented"
    assert scene.data["load"]["displacement"] == 0.09
