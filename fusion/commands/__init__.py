"""Subcommands of the ``fusion`` command line, one module each.

:data:`fusion.cli.COMMANDS` lists them (name -> module, one-line help); a module is imported only
when its command is chosen, so it may import what it needs at the top. Each module defines
``register(subparsers)``, which adds the parser under the registry's name and help, and
``run(args) -> int``. The parser's ``set_defaults`` declares

- ``handler=run``;
- ``inputs=("opt", ...)``: the dests of the options naming files the command reads (checked to
  exist, and never to be the ``--out`` file, before any work);
- ``out_is_dir=True`` when ``--out`` is a folder (``--out -`` is then refused);
- ``out_stdout=False`` when a one-file output cannot go to standard output;
- ``out_files=("a.csv", ...)``: the files a folder ``--out`` receives;
- ``more_outputs=("opt", ...)``: the dests of other options naming files the command writes;
- ``input_files={"opt": ("a.json", ...)}``: the files read inside a folder input;
- ``outputs_together=False`` when the command reads back files it wrote (by default every
  output of a run is committed at its end, all or none: :func:`fusion._output.outputs_together`).

No output may be an input or another output (by any path or link): :func:`fusion.cli.check_paths`
refuses it before any work.

Errors are ValueError/OSError with a message naming the file or option; ``fusion.cli.main`` prints
them as one line with exit code 2.
"""

# The package imports none of its modules (each loads only its own dependencies when
# imported); `from fusion.commands import *` imports them all.
__all__ = [
    "acquire",
    "crossings",
    "demo",
    "import_data",
    "localize",
    "localize_events",
    "passive",
    "report",
    "simulate",
    "smooth",
    "tma",
    "tqi",
    "track",
    "train_validator",
]
