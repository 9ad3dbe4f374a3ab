#!/usr/bin/env python3
"""Checks that no project include in src/ or cuda/ runs upward (docs/ARCHITECTURE.md).

Layers, lowest first: grid < common (and the GDAL helpers) < label, measure < sites, write <
pipeline < the API (src/voronoi.*). A file may include its own layer's headers and lower ones.
Inside the labeller, its API headers (labeller.hpp, label_session.hpp) sit above its stages: no
other label/ header includes them. Prints each upward include; exit status 1 when there is one.

  python3 scripts/check_include_layers.py [repository root]
"""
import pathlib
import re
import sys

LAYERS = {"grid": 0, "common": 1, "gdal": 1, "label": 2, "measure": 2, "sites": 3, "write": 3, "pipeline": 4}
API_LAYER = 5  # src/voronoi.hpp, src/voronoi.cpp
# cuda/ holds the back ends of label and measure (src/CMakeLists.txt: qtmv_cuda_back_end).
CUDA_LAYER = {"edge_solver_cuda.cu": LAYERS["measure"]}
LABEL_API_HEADERS = {"label/labeller.hpp", "label/label_session.hpp"}
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')


def layer_of(path: str):
    """The layer of a file named relative to src/ (or cuda/<name>), None when outside them."""
    parts = path.split("/")
    if parts[0] == "cuda":
        return CUDA_LAYER.get(parts[-1], LAYERS["label"])
    if len(parts) == 1:
        return API_LAYER if parts[0].startswith("voronoi.") else None
    return LAYERS.get(parts[0])


def main() -> int:
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parent.parent)
    files = [p for d in ("src", "cuda") for p in sorted((root / d).rglob("*"))
             if p.suffix in (".hpp", ".cpp", ".cu", ".cuh", ".h")]
    problems = []
    for path in files:
        rel = path.relative_to(root).as_posix()
        name = rel[len("src/"):] if rel.startswith("src/") else rel
        own = layer_of(name)
        if own is None:
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            match = INCLUDE.match(line)
            if not match:
                continue
            target = match.group(1)
            if "/" not in target and (path.parent / target).exists():
                target = (path.parent / target).relative_to(root / "src").as_posix() \
                    if rel.startswith("src/") else target
            theirs = layer_of(target)
            if theirs is not None and theirs > own:
                problems.append(f"{rel}:{number}: includes {target} (layer {theirs}) from layer {own}")
            elif (target in LABEL_API_HEADERS and name.startswith("label/") and name.endswith(".hpp")
                  and name not in LABEL_API_HEADERS):
                problems.append(f"{rel}:{number}: a labeller stage's header includes its API header {target}")
    for problem in problems:
        print(problem)
    print(f"{len(files)} files, {len(problems)} upward include{'s' if len(problems) != 1 else ''}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
