"""What a free-form import did not convert: grouped, said on stderr, made an error by --strict.

An IGES import report (tracer.formats.iges) lists every entity that could have become a
surface and did not, as `losses`: groups by entity type and kind (unsupported entity type,
conversion failed, unreadable directory entry, unreadable parameter data, orphan: a
subordinate surface whose parent was not converted), each with its directory-entry numbers
and the first entry's reason; `notes` says what is wrong with the file as a whole (cut
short, section counts that disagree). `psrt render` and `psrt trace` print them, `--stats`
holds them, the viewer's Scene panel shows them, and `--strict` turns any of them into an
error.
"""
from __future__ import annotations

from tracer.errors import SceneError

SHOWN_DE = 8  # directory-entry numbers a line lists before "..."


def group_losses(lost: list[dict], surface_types=()) -> list[dict]:
    """[{'type', 'kind', 'count', 'de': [...], 'reason': the first entry's}]: surfaces first,
    then most first."""
    groups: dict = {}
    for x in sorted(lost, key=lambda x: x["de"]):
        g = groups.setdefault((x["type"], x["kind"]), {"type": x["type"], "kind": x["kind"],
                                                       "count": 0, "de": [],
                                                       "reason": x["reason"]})
        g["count"] += 1
        g["de"].append(x["de"])
    return sorted(groups.values(), key=lambda g: (g["type"] not in surface_types, -g["count"],
                                                  str(g["type"]), g["kind"]))


def has_losses(report: dict) -> bool:
    return bool(report.get("losses") or report.get("notes"))


def _de_list(de: list) -> str:
    shown = ", ".join(map(str, de[:SHOWN_DE]))
    return shown + (f", ... ({len(de)} in all)" if len(de) > SHOWN_DE else "")


def group_line(g: dict) -> str:
    """'150 x 144 (conversion failed): DE 1, 3, ...; first: DE 1: <reason>'."""
    t = g["type"] if g["type"] is not None else "?"
    return (f"{g['count']} x {t} ({g['kind']}): DE {_de_list(g['de'])}; first: DE {g['de'][0]}: "
            f"{g['reason']}")


def loss_lines(source: str, report: dict) -> list[str]:
    """stderr lines about one file's losses (a heading, a line a group, the notes); [] if none."""
    if not has_losses(report):
        return []
    lost, surfaces = report.get("lost", 0), report.get("lost_surfaces", 0)
    head = (f"{source}: {lost} {report.get('format', '').upper()} "
            f"entit{'y' if lost == 1 else 'ies'} not converted ({surfaces} of them "
            f"surface{'' if surfaces == 1 else 's'})" if lost else f"{source}: the file is damaged")
    return ([head + " (--strict makes this an error):"]
            + [f"  note: {n}" for n in report.get("notes", [])]
            + [f"  {group_line(g)}" for g in report.get("losses", [])])


def summary(report: dict) -> dict:
    """The losses of one import for --stats (JSON-ready)."""
    return {"format": report.get("format"), "surfaces": report.get("surfaces"),
            "lost": report.get("lost", 0), "lost_surfaces": report.get("lost_surfaces", 0),
            "losses": report.get("losses", []),
            "notes": report.get("notes", [])}


def summary_line(report: dict) -> str:
    """One line: how many entities were lost, of which types and kinds, and the first reason."""
    groups = report.get("losses", [])
    what = "; ".join(f"{g['count']} x {g['type'] if g['type'] is not None else '?'} {g['kind']}"
                     for g in groups[:3]) + ("; ..." if len(groups) > 3 else "")
    first = (report["notes"][0] if report.get("notes")
             else f"first: DE {groups[0]['de'][0]}: {groups[0]['reason']}" if groups else "")
    lost = report.get("lost", 0)
    return (f"{lost} entit{'y' if lost == 1 else 'ies'} not converted"
            + (f" ({what})" if what else "") + (f"; {first}" if first else ""))


def strict_check(import_report: dict) -> None:
    """--strict: a SceneError (one line) naming the first file that lost anything."""
    for source, report in import_report.items():
        if has_losses(report):
            raise SceneError(f"--strict: {summary_line(report)}", path=source)
