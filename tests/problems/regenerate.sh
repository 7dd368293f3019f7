#!/usr/bin/env bash
# Regenerates the committed corpus of constraint problems (tests/problem_corpus.rs re-solves it):
# each entry steps a built-in scene with `gelenk export-problems` and keeps one step's directory
# (problem.json, cone.json, lcp.npz, qp.npz for QPs, meta.json) as tests/problems/NAME.
# Run after a deliberate change of a solver, the residuals, the scenes or the file formats, and
# review the meta.json differences (statuses, residuals, w) before committing them.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --quiet
bin="${CARGO_TARGET_DIR:-target}/release/gelenk"
corpus=tests/problems
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# add NAME SCENE FRICTION STEP
add() {
    local name=$1 scene=$2 friction=$3 step=$4
    "$bin" export-problems "$scene" --steps $((step + 1)) --only "$step" --friction "$friction" \
        --out "$tmp/$name" >/dev/null
    rm -rf "${corpus:?}/$name"
    mv "$tmp/$name/step-$(printf %04d "$step")" "$corpus/$name"
    echo "$name"
}

# Frictionless: pure QPs (box bounds and equalities only).
add box-flat-0000 box-flat cone 0                 # 4 coplanar contacts: A is singular
add box-flat-0040 box-flat cone 40
add four-bar-0000 four-bar cone 0                 # hinge loop closure: 3 of 5 rows are zero
add four-bar-0050 four-bar cone 50
add limit-pendulum-0020 limit-pendulum cone 20    # impact on the limit, with restitution
add limit-pendulum-0059 limit-pendulum cone 59    # resting on the limit
# Friction cone: second-order cone programs.
add box-drop-cone-0015 box-drop cone 15           # first impact on a corner, sliding
add box-drop-cone-0045 box-drop cone 45           # two contacts, one separating
add box-drop-cone-0064 box-drop cone 64           # four contacts, sliding
add box-drop-cone-0100 box-drop cone 100          # resting flat: 4 coplanar contacts with friction
add sphere-incline-cone-0000 sphere-incline cone 0  # launched without spin: friction spins it up
add sphere-incline-cone-0030 sphere-incline cone 30 # rolling (sticking contact)
add stack2-cone-0000 stack2 cone 0
add stack2-cone-0001 stack2 cone 1                # resting stack: redundant contacts, A singular
# Friction pyramid: QPs with facet inequalities.
add box-drop-pyramid4-0015 box-drop pyramid:4 15
add box-drop-pyramid4-0072 box-drop pyramid:4 72  # resting flat
add box-drop-pyramid8-0066 box-drop pyramid:8 66
add sphere-incline-pyramid4-0008 sphere-incline pyramid:4 8
add stack2-pyramid4-0004 stack2 pyramid:4 4       # resting stack, pyramid
add stack2-pyramid8-0008 stack2 pyramid:8 8
add stack10-pyramid4-0000 stack10 pyramid:4 0     # the large one: 120 rows, 40 contacts

# The table of tests/problems/README.md, from the new meta.json files.
echo
echo "| problem | scene | step | rows | contacts | nv | friction | formulation | clarabel | lemke | pgs |"
echo "|---|---|---:|---:|---:|---:|---|---|---|---|---|"
for dir in "$corpus"/*/; do
    name=$(basename "$dir")
    "$bin" solve-problem "$dir" --solver clarabel --json 2>/dev/null | python3 -c '
import json, sys
name = sys.argv[1]
run = json.load(sys.stdin)
problem = json.load(open(sys.argv[2] + "/problem.json"))
meta = json.load(open(sys.argv[2] + "/meta.json"))
scene, step = name.rsplit("-", 1)
for kind in ("-cone", "-pyramid4", "-pyramid8"):
    scene = scene.removesuffix(kind)
contacts = problem["contacts"]
if not contacts:
    friction = "—"
elif all(c["mu"] == 0 for c in contacts):
    friction = "μ = 0"
else:
    f = problem["friction"]
    friction = "cone" if f["model"] == "cone" else "pyramid:%d" % f["facets"]
def status(kind):
    s = meta["solutions"][kind]
    return s["status"] if s.get("certified") is None else "%s %.0e" % (s["status"], s["certified"])
print("| `%s` | %s | %d | %d | %d | %d | %s | %s | %s | %s | %s |" % (
    name, scene, int(step), problem["rows"], len(contacts), problem["nv"], friction,
    run["formulation"], status("clarabel"), status("lemke"), status("pgs")))
' "$name" "$dir"
done

# The standard formats' samples (tests/corpus_formats.rs, the fclib module's tests): CBF of two
# cone problems, QPS of two QPs, FCLIB of a contact-only cone problem (needs --features fclib).
mkdir -p "$corpus/formats"
for name in stack2-cone-0000 sphere-incline-cone-0030; do
    "$bin" corpus convert "$corpus/$name" --out "$corpus/formats/$name.cbf" >/dev/null
done
for name in stack2-pyramid4-0004 box-flat-0000; do
    "$bin" corpus convert "$corpus/$name" --out "$corpus/formats/$name.qps" >/dev/null
done
if "$bin" corpus convert "$corpus/stack2-cone-0000" --out "$tmp/probe.hdf5" >/dev/null 2>&1; then
    cp "$tmp/probe.hdf5" "$corpus/formats/stack2-cone-0000.hdf5"
fi
