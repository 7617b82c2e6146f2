"""The choices of a component option and their help, read from the registry's declarations
(names and descriptions: nothing is imported), so a plugin's component appears beside the
built-in ones."""

from __future__ import annotations

from rbbench.registry import default_registry

#: a description longer than this is cut at a word (``rbbench plugins`` shows it whole)
MAX_DESCRIPTION = 72


def _short(text: str) -> str:
    """The description's first clause (before ``:`` or ``;``), at most
    :data:`MAX_DESCRIPTION` characters, ``%`` escaped for argparse."""
    for sep in (": ", "; "):
        head = text.split(sep, 1)[0]
        if len(head) >= 12:
            text = head
    if len(text) > MAX_DESCRIPTION:
        cut = text[:MAX_DESCRIPTION]
        at = max(cut.rfind(", "), cut.rfind(" ("))
        text = (cut[:at] if at >= 30 else cut.rsplit(" ", 1)[0]) + " ..."
    return text.replace("%", "%%")


def role_choices(role: str, extra: tuple[str, ...] = ()) -> list[str]:
    """``extra`` (e.g. ``"auto"``) and the registered names of ``role``."""
    return [*extra, *default_registry().names(role)]


def role_help(role: str, lead: str, extra: dict[str, str] | None = None) -> str:
    """``lead``, then each registered component of ``role`` with its short description
    (``extra``: values that are not components, e.g. ``{"auto": "the formulation's rule"}``,
    listed first)."""
    reg = default_registry()
    items = [f"{k}: {v}" for k, v in (extra or {}).items()]
    items += [f"{s.name}: {_short(s.description)}" for s in reg.specs(role)]
    return f"{lead}. Registered (rbbench plugins --role {role}): " + "; ".join(items)


def component_arg(group, flag: str, role: str, lead: str,
                  extra: dict[str, str] | None = None, **kwargs) -> None:
    """``group.add_argument(flag)`` whose choices and help are the registered components of
    ``role`` (plus ``extra``); ``kwargs`` go to ``add_argument`` (``default``, ``dest``)."""
    group.add_argument(flag, choices=role_choices(role, tuple(extra or ())),
                       metavar=flag.lstrip("-").upper().replace("-", "_"),
                       help=role_help(role, lead, extra), **kwargs)
