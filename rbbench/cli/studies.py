"""``rbbench studies STUDY``: the side-by-side studies that carry their own ``add_parser``
and ``run`` (pymor-thermal-block, heat-seed: issue 18; shape-side-by-side: issue 15;
snapshot-workers: issue 17)."""

from __future__ import annotations


def add_parser(sub) -> None:
    """Register ``studies`` and one subcommand per study on the CLI's subparsers."""
    from rbbench.studies import heat_seed, pymor_thermal_block, shape_side_by_side, snapshot_workers

    st = sub.add_parser("studies", help="side-by-side studies (pymor-thermal-block, heat-seed, "
                        "shape-side-by-side, snapshot-workers)")
    group = st.add_subparsers(dest="study", required=True, metavar="STUDY")
    for module in (pymor_thermal_block, heat_seed, shape_side_by_side, snapshot_workers):
        module.add_parser(group).set_defaults(func=module.run)
