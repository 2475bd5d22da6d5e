"""`psrt study --report DIR` (issue 14 item 4): one Markdown file readable without the tool: the
machine, the study's chart and table, the coherence benchmark's tables and the stress table."""
from __future__ import annotations

import datetime
import os
import platform


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _memory_gib() -> str:
    try:
        return f"{os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES') / 2 ** 30:.1f} GiB"
    except (ValueError, OSError, AttributeError):
        return "unknown"


def machine() -> dict:
    """What the run's figures depend on: CPU, cores, memory, system, Python and library versions."""
    import numba
    import numpy
    out = {"date (UTC)": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M"),
           "CPU": _cpu_model(), "cores": str(os.cpu_count()), "memory": _memory_gib(),
           "system": f"{platform.system()} {platform.release()}", "Python": platform.python_version(),
           "numpy": numpy.__version__, "numba": numba.__version__}
    try:
        import embreex
        import trimesh
        out["trimesh / embreex"] = f"{trimesh.__version__} / {getattr(embreex, '__version__', '?')}"
    except ImportError:
        pass
    return out


def document(scene: str, study_md: str, chart_name: str, coherence_text: str | None, stress_text: str | None,
             machine_info: dict, notes: dict) -> str:
    """The report: headings, the machine table, the chart image, the tables (fixed-width ones fenced)."""
    parts = [f"# psrt study of `{scene}`", "",
             "Run time against error on the same primary rays (Dammertz table 2.9, extended to the "
             "peers), the coherence benchmark and the numerical stress suite, on the machine below.", "",
             "## Machine", "", "| | |", "|---|---|"]
    parts += [f"| {k} | {v} |" for k, v in machine_info.items()]
    parts += ["", "## Run time against error", "", f"![time against error]({chart_name})", "",
              notes.get("study", ""), "", study_md]
    if coherence_text is not None:
        parts += ["## Coherence (`psrt bench --coherence`)", "", notes.get("coherence", ""), "",
                  "```", coherence_text, "```", ""]
    if stress_text is not None:
        parts += ["## Numerical stress (`psrt stress`)", "", notes.get("stress", ""), "", "```", stress_text, "```", ""]
    return "\n".join(parts).rstrip() + "\n"
