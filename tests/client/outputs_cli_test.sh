#!/usr/bin/env bash
# What a CLI user meets first (issue 25): mesh --out FILE by extension (.ply, .glb, .gltf,
# .obj) and the refusals of a name it cannot write; "did you mean" and a short usage on a
# mistake; --json in one key style with numbers as numbers (stats too); bash completion
# generated from the option table.
#   outputs_cli_test.sh MLCLUST_BINARY DATA_DIR
set -euo pipefail
mlclust=$1
data=$2
work=$(mktemp -d)
server_pid=
trap '[ -n "$server_pid" ] && kill "$server_pid" 2> /dev/null; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
mesh=$data/fandisk.off  # 12,946 faces

# --out by extension: the PLY is --ply's byte for byte; glTF carries _CLUSTER; the OBJ has
# a group per run of faces of one cluster, whose names are the labels of --labels.
for ext in ply glb gltf obj; do
  "$mlclust" mesh "$mesh" -k 20 --out "$work/out.$ext" --quiet > /dev/null \
    || fail "--out .$ext failed"
done
"$mlclust" mesh "$mesh" -k 20 --ply "$work/ply.ply" --labels "$work/labels.txt" --quiet \
  > /dev/null
cmp "$work/out.ply" "$work/ply.ply" || fail "--out .ply differs from --ply"
[ "$(head -c 4 "$work/out.glb")" = "glTF" ] || fail "--out .glb: not a GLB"
grep -q '"_CLUSTER"' "$work/out.glb" || fail "--out .glb: no _CLUSTER attribute"
grep -q '"_CLUSTER"' "$work/out.gltf" || fail "--out .gltf: no _CLUSTER attribute"
awk '/^g cluster_/ { sub("g cluster_", ""); group = $0 } /^f / { print group }' \
  "$work/out.obj" > "$work/obj_labels.txt"
cmp "$work/obj_labels.txt" "$work/labels.txt" || fail "--out .obj: groups are not the labels"
[ "$(grep -c '^v ' "$work/out.obj")" -eq 6475 ] || fail "--out .obj: not the input's vertices"
# Two consecutive faces of one cluster share a group line: fewer groups than faces.
[ "$(grep -c '^g ' "$work/out.obj")" -lt 12946 ] || fail "--out .obj: a group per face"

# Refusals, before any job runs, with nothing written (exit 2, the flag and file named).
refused() {  # refused EXPECTED_MESSAGE ARGS...: exit 2, the message on stderr, no stdout
  local message=$1
  shift
  set +e
  "$mlclust" "$@" > "$work/stdout.txt" 2> "$work/stderr.txt"
  local rc=$?
  set -e
  [ "$rc" -eq 2 ] || fail "$*: exit $rc, not 2"
  grep -qF -- "$message" "$work/stderr.txt" || fail "$*: said $(cat "$work/stderr.txt")"
  [ ! -s "$work/stdout.txt" ] || fail "$*: printed $(cat "$work/stdout.txt")"
}
refused "mlclust: --ply $work/x.glb: --ply writes a PLY file, which the name .glb would misname; give --out $work/x.glb to write glTF (its format follows the extension), or a .ply name" \
  mesh "$mesh" -k 20 --ply "$work/x.glb"
refused "mlclust: --out $work/x.stl: cannot write '.stl' files (the format follows the extension: .ply, .glb, .gltf or .obj)" \
  mesh "$mesh" -k 20 --out "$work/x.stl"
refused "cannot write a file without extension" mesh "$mesh" -k 20 --out "$work/noext"
refused "--labels, --ply and --out need --clusters K" mesh "$mesh" --out "$work/x.ply"
refused "--ply writes PLY: give a .ply name" watch job-1 --server 127.0.0.1:1 --ply "$work/x.txt" \
  --mesh "$mesh" -k 2
for f in x.glb x.stl noext x.ply x.txt; do
  [ ! -e "$work/$f" ] || fail "$f was written by a refused command"
done

# A mistake prints a short usage and what was meant; the full help only on --help.
refused "mlclust: unknown command 'meshh' (did you mean 'mesh'?)" meshh x
[ "$(wc -l < "$work/stderr.txt")" -le 3 ] || fail "meshh: $(wc -l < "$work/stderr.txt") lines"
grep -qF "commands: serve, mesh, points" "$work/stderr.txt" || fail "meshh: no command list"
refused "usage: mlclust COMMAND" 
[ "$(wc -l < "$work/stderr.txt")" -le 3 ] || fail "no command: $(wc -l < "$work/stderr.txt") lines"
refused "unknown option --clusterz; did you mean --clusters?" mesh "$mesh" --clusterz 3
refused "no command 'poitns' (did you mean 'points'?)" help poitns
"$mlclust" mesh --help > "$work/help.txt"
[ "$(wc -l < "$work/help.txt")" -gt 100 ] || fail "mesh --help is not the full help"

# Progress: a bar with the share done redrawn in place on a terminal (a pseudo-terminal
# here); nothing on a pipe; with --progress, lines on a pipe; none with --quiet.
/usr/bin/python3 - "$mlclust" "$mesh" <<'PY' || fail "progress on a terminal"
import os, pty, subprocess, sys
def on_pty(*extra):
    master, slave = pty.openpty()
    process = subprocess.Popen([sys.argv[1], "mesh", sys.argv[2], "-k", "20", *extra],
                               stdin=slave, stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    out = b""
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:
            break
        if not data:
            break
        out += data
    assert process.wait() == 0
    os.close(master)
    return out.decode()
out = on_pty()
assert out.startswith("\r\x1b[Kmlclust: queued, 0 ahead ["), repr(out[:200])
assert out.endswith("[########################] 100%  12946 levels, 1 clusters  "
                    + out.rsplit("clusters  ", 1)[1]), repr(out[-200:])
assert out.endswith("\r\n") and out.count("\n") == 1, repr(out[-200:])
assert on_pty("--quiet") == "", "--quiet on a terminal"
PY
"$mlclust" mesh "$mesh" -k 20 > /dev/null 2> "$work/piped.txt"
[ ! -s "$work/piped.txt" ] || fail "progress on a pipe: $(cat "$work/piped.txt")"
"$mlclust" mesh "$mesh" -k 20 --progress > /dev/null 2> "$work/asked.txt"
tail -1 "$work/asked.txt" | grep -q "^mlclust: cluster \[#*\] 100%  12946 levels, 1 clusters  0:0" \
  || fail "--progress on a pipe: $(cat "$work/asked.txt")"
! grep -q $'\r' "$work/asked.txt" || fail "--progress on a pipe redraws in place"

# --json: keys in one style (snake_case) at every depth, numbers as numbers.
"$mlclust" mesh "$mesh" -k 20 --out "$work/j.obj" --levels-csv "$work/j.csv" --json --quiet \
  > "$work/summary.json"
"$mlclust" serve --listen 127.0.0.1:0 2> "$work/serve.log" &
server_pid=$!
for _ in $(seq 100); do
  grep -q "listening on port" "$work/serve.log" && break
  sleep 0.1
done
port=$(sed -n 's/.*listening on port \([0-9]*\).*/\1/p' "$work/serve.log")
"$mlclust" mesh "$mesh" -k 5 --server "127.0.0.1:$port" --quiet > /dev/null
"$mlclust" stats --server "127.0.0.1:$port" --json > "$work/stats.json"
"$mlclust" stats --server "127.0.0.1:$port" > "$work/stats.txt"
"$mlclust" info --json > "$work/info.json"
# stats shows every field of the Stats message, zero included (no job failed here, so
# jobs_failed is 0), in both forms: one "name: value" line each, in the proto's order, and
# a JSON member each; a proto3 `optional` field only where the server sets it.
/usr/bin/python3 - "$(dirname "$0")/../../proto/mlclust/v1/mlclust.proto" "$work/stats.txt" \
  "$work/stats.json" <<'PY' || fail "stats fields: $(cat "$work/stats.txt")"
import json, re, sys
proto, text, document = open(sys.argv[1]).read(), open(sys.argv[2]).read(), json.load(open(sys.argv[3]))
body = re.search(r"^message Stats \{(.*?)^\}", proto, re.S | re.M).group(1)
fields = re.findall(r"^\s*(optional\s+)?\w+\s+(\w+)\s*=\s*\d+;", body, re.M)
assert len(fields) > 30, fields
lines = [line.split(": ", 1) for line in text.splitlines()]
names = [name for name, _ in lines]
expected = [name for optional, name in fields if not optional or name in names]
assert names == expected, (names, expected)
for optional, name in fields:
    assert optional or name in document, f"--json lacks {name}"
values = dict(lines)
for name in ("jobs_failed", "jobs_cancelled", "jobs_rejected", "calls_refused",
             "readers_cut_off", "uploads_timed_out", "results_dropped"):
    assert values[name] == "0" and document[name] == 0, (name, values[name], document[name])
assert values["jobs_succeeded"] == "1" and values["draining"] == "false", values
PY
/usr/bin/python3 - "$work/summary.json" "$work/stats.json" "$work/info.json" <<'PY' \
  || fail "--json: $(cat "$work/summary.json" "$work/stats.json")"
import json, re, sys
summary, stats, info = (json.load(open(p)) for p in sys.argv[1:])

def keys(value, where):
    if isinstance(value, dict):
        for key, item in value.items():
            assert re.fullmatch(r"[a-z][a-z0-9_]*", key), f"{where}: key {key!r}"
            keys(item, f"{where}.{key}")
    elif isinstance(value, list):
        for item in value:
            keys(item, where)

for name, document in (("summary", summary), ("stats", stats), ("info", info)):
    keys(document, name)
assert summary["outputs"] == {"levels_csv": sys.argv[1].replace("summary.json", "j.csv"),
                              "out": sys.argv[1].replace("summary.json", "j.obj")}, summary
assert summary["faces"] == 12946 and summary["level"]["clusters"] == 20, summary
for key in ("jobs_accepted", "jobs_succeeded", "max_input_bytes", "upload_bytes_limit",
            "queue_capacity", "retention_seconds"):
    assert type(stats[key]) is int, (key, stats[key])
assert stats["jobs_succeeded"] == 1 and stats["jobs_accepted"] == 1, stats
assert type(info["max_input_bytes"]) is int, info["max_input_bytes"]
PY

# Bash completion from the option table: every flag mesh --help names completes.
"$mlclust" completion bash > "$work/completion.bash"
bash -c '
source "$1"
complete_words() { COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1)); _mlclust; echo "${COMPREPLY[*]}"; }
[ "$(complete_words mlclust mes)" = "mesh" ] || exit 11
[ "$(complete_words mlclust mesh --clu)" = "--clusters" ] || exit 12
[ "$(complete_words mlclust points --auto-k "")" = "bic bic-first-decrease elbow" ] || exit 13
[ "$(complete_words mlclust help poi)" = "points" ] || exit 14
# The rows of the help: "  --name VALUE  help" or "  -k, --name K  help".
for flag in $(grep -oE -- "^ +(-[a-z], )?--[a-z][a-z0-9-]*" "$2" | grep -oE -- "--[a-z0-9-]+$"); do
  case " $(complete_words mlclust mesh --) " in *" $flag "*) ;; *) echo "$flag"; exit 15 ;; esac
done
' completion "$work/completion.bash" "$work/help.txt" || fail "completion: exit $?"
echo "outputs_cli_test: ok"
