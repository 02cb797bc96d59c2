"""``python -m optimizers.reproduce <scenario>``: published against measured values.

Each paper's reproduction lives in its own module ``optimizers.reproduce.<scenario>`` exposing
``main(argv: list[str]) -> int``. All accept ``--quick`` and ``--json FILE``; the JSON has the
keys ``published`` and ``measured``; plots go to ``--out`` (default ``results/<scenario>/``).
"""

SCENARIOS = {
    "zhu2007": "optimizers.reproduce.zhu2007",
    "peng2012": "optimizers.reproduce.peng2012",
    "wang2001": "optimizers.reproduce.wang2001",
    "peng_mars": "optimizers.reproduce.peng_mars",
    "wang2003": "optimizers.reproduce.wang2003",
}
