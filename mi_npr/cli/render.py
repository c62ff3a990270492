"""``mi-npr render``: scenes with every drawing asked for, one EXR with every layer and a
picture per drawing (:func:`mi_npr.pipeline.render_layers`,
:func:`mi_npr.io.write_layered_outputs`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..batch import check_outputs, check_unique_stems, run_jobs, scene_drawings
from ..drawings import DRAWINGS
from ..io import check_writable_dir, write_layered_outputs
from ..io.svg import SVG_IMAGE
from ..pipeline import render_layers
from ..session import RENDER_PARAMS
from ._common import (
    add_drawings,
    add_paper,
    add_scenes,
    asked_drawings,
    drawing_values,
    exit_code,
    progress,
    resolution,
    result_line,
    spp_and_defines,
)

NAME = "render"
HELP = "render scenes: one EXR with every layer, a PNG per drawing (--lines, --contours...)"
#: The command's own parameter tables (its drawing flags come from the registry).
TABLES = (RENDER_PARAMS,)
SVG_IMAGE_HELP = "the beauty in <stem>_contours.svg: embedded once (default), linked, or none"


def add_svg_image(cmd: argparse.ArgumentParser, help: str) -> None:
    cmd.add_argument("--svg-image", choices=SVG_IMAGE, default="embed", help=help)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scenes(cmd, NAME)
    add_drawings(cmd, list(DRAWINGS))
    add_paper(cmd, "<stem>")
    add_svg_image(cmd, SVG_IMAGE_HELP)
    cmd.add_argument(
        "--no-beauty-in-svg", action="store_true", help="do not embed the beauty in the SVG"
    )


def render_scenes(args: argparse.Namespace, drawings: tuple[str, ...], only: str | None) -> int:
    """``render`` (``only=None``) and its shorthands ``contours`` and ``raytree``: each scene
    rendered and written as soon as it is done, one line each."""
    check_unique_stems(args.scenes)
    outdir = check_writable_dir(args.output, create=True)
    spp, defines = spp_and_defines(args)
    no_image = getattr(args, "no_beauty_in_svg", False)
    svg_image = "none" if no_image else getattr(args, "svg_image", "embed")
    check_outputs(
        [
            (
                s,
                outdir,
                Path(s).stem,
                [*drawings, *(scene_drawings(s, defines) if only is None else [])],
            )
            for s in args.scenes
        ],
        only=only,
        svg_image=svg_image,
    )
    params = drawing_values(args)
    bars = progress(args)

    def job(scene: str) -> list[Path]:
        result = render_layers(
            scene,
            drawings,
            params,
            scene_drawings=only is None,
            seed=args.seed,
            progress=bars,
            spp=spp,
            defines=defines,
            resolution=resolution(args),
        )
        return write_layered_outputs(
            result,
            outdir,
            Path(scene).stem,
            only=only,
            line_color=params.get("line_color"),
            paper=getattr(args, "paper", None),
            svg_image=svg_image,
        )

    results = run_jobs(args.scenes, job, bars, args.traceback, on_result=result_line)
    return exit_code(results)


def run(args: argparse.Namespace) -> int:
    return render_scenes(args, asked_drawings(args), None)
