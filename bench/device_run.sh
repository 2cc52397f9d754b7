#!/usr/bin/env bash
# The ONE command of a device call that takes issue 10's GPU-node figures (CONTRIBUTING.md,
# "GPU-node figures"): run there, from the repository root, with the bundle that
# bench/device_bundle.sh made here carried along:
#
#   run(command="bash bench/device_run.sh --budget 540", carry=[".devbundle"], timeout_s=600)
#   run(command="bash bench/device_run.sh --budget 540 --part 2", ...)   # next session: 2, 3
#
# One part per session: with the start, a 540-s call leaves about 4 of the 15 minutes. A
# second call in the same session only if `status` says budget_left_s >= 300 and the machine
# is still warm: --budget $((budget_left_s - 120)), timeout_s that + 30, then give_back.
#
#   --budget S        seconds for everything (set-up included; default 540): the rows get
#                     what the set-up leaves, less 10 s for the last copies
#   --part 1|2|3|all  bench/gpu_node.sh's rows (default 1: the headline rows, ~8 minutes;
#                     2 and 3: the rest, one call each)
#   --quick           gpu_node.sh's small sizes
#   --allow-software  accept a software renderer (llvmpipe) and unpack the loaders under the
#                     bundle instead of /: only to prove the script on a machine without a
#                     GPU (BENCHMARKS.md, "Taking the GPU-node figures in one device call")
#   --gl-root DIR     unpack the loaders' .debs under DIR and put its lib folder on
#                     LD_LIBRARY_PATH (default: / and ldconfig; --allow-software: WORK/glroot)
#   --threads N       the CPU stages' threads (default: nproc; a line in the log and env.txt
#                     says so when that is not the 16 cores the issue's figures assume)
#   --bundle-cxx      use the bundle's C++ runtime even where the device's is new enough
#   --bundle DIR      the bundle (default .devbundle)
#   --work DIR        where the meshes are unpacked (default /tmp/mlclust_device_run: never
#                     inside the bundle, which must stay small enough to travel)
#   --dry-run         print what it would do and the rows with their estimates; run nothing
#
# Steps: (1) the device's glibc against the bundle's need; (2) the GL/EGL loaders' .debs
# unpacked (`dpkg -x` to / and ldconfig, as /work/.library/device/README.md says);
# (3) LD_LIBRARY_PATH to the bundle's lib/ for our binaries (not for python3: the PyTorch
# peer runs with the device's own libraries); (4) __EGL_VENDOR_LIBRARY_FILENAMES set to
# NVIDIA's vendor file when glvnd's default folders hold none; (5) mlclust-gpu-info must
# name an NVIDIA renderer, else it says why and exits 3 before any row (no llvmpipe
# figures by mistake); (6) the meshes unpacked and armadillo_1m made again (md5 checked);
# (7) bench/gpu_node.sh --build BUNDLE/build --part N --budget LEFT --out $OUT.
# Everything goes to $OUT (default WORK/out): device_run.log, env.txt, gpu_node.csv and
# gpu_node_status.tsv, written row by row, so a kill at the call's limit loses nothing
# that was written.
set -euo pipefail
started=$SECONDS
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"

budget=540 part=1 quick=0 allow_software=0 bundle=.devbundle dry_run=0 bundle_cxx=0 gl_root=""
work=/tmp/mlclust_device_run threads=""
while [ $# -gt 0 ]; do
  case "$1" in
    --budget) budget="${2:?}"; shift 2 ;;
    --part) part="${2:?}"; shift 2 ;;
    --quick) quick=1; shift ;;
    --allow-software) allow_software=1; shift ;;
    --bundle) bundle="${2:?}"; shift 2 ;;
    --bundle-cxx) bundle_cxx=1; shift ;;
    --gl-root) gl_root="${2:?}"; shift 2 ;;
    --work) work="${2:?}"; shift 2 ;;
    --threads) threads="${2:?}"; shift 2 ;;
    --dry-run) dry_run=1; shift ;;
    -h | --help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
    *) echo "device_run: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[[ "$budget" =~ ^[0-9]+$ ]] || { echo "device_run: --budget takes whole seconds" >&2; exit 2; }
node_args=(--part "$part")
[ "$quick" = 1 ] && node_args+=(--quick)

if [ "$dry_run" = 1 ]; then
  echo "device_run: would unpack $bundle/gl/*.deb to ${gl_root:-$([ "$allow_software" = 1 ] &&
    echo "$work/glroot" || echo /)}, set LD_LIBRARY_PATH=$bundle/lib, check the renderer" \
    "($([ "$allow_software" = 1 ] && echo "any" || echo "NVIDIA only")), unpack the meshes," \
    "make armadillo_1m, then run within $budget s (set-up included):"
  exec bash bench/gpu_node.sh --dry-run "${node_args[@]}"
fi

mkdir -p "$work"
work="$(cd "$work" && pwd)"
out="${OUT:-$work/out}"
mkdir -p "$out"
exec > >(tee -a "$out/device_run.log") 2>&1
tee_pid=$!
# On every exit, let tee write the last lines (the status table) before the call returns.
trap 'exec >&- 2>&-; wait "$tee_pid" 2>/dev/null' EXIT
bundle="$(cd "$bundle" && pwd)"
manifest="$bundle/MANIFEST"
[ -f "$manifest" ] || { echo "device_run: $manifest missing: run bench/device_bundle.sh here and carry $bundle" >&2; exit 1; }
echo "device_run: $(date -u +%FT%TZ), budget ${budget}s, part $part, quick $quick"
{
  echo "# device_run $(date -u +%FT%TZ)"
  uname -a
  echo "cores $(nproc)"
  grep -m1 'model name' /proc/cpuinfo || true
  command -v nvidia-smi >/dev/null && nvidia-smi -L && nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv || echo "no nvidia-smi"
  ldd --version | awk 'NR == 1'
  sed -n '1,4p' "$manifest"
} >"$out/env.txt" 2>&1 || true

# (1) glibc: the binaries were linked against this machine's; the device's must not be older.
# (awk reads to the end: under pipefail an early exit of the reader fails the writer.)
have="$(ldd --version 2>&1 | awk 'NR == 1 { print $NF }')"
glibc_at_least() { [ "$(printf '%s\n%s\n' "$1" "$have" | sort -V | awk 'NR == 1')" = "$1" ]; }
need="$(sed -n 's/^glibc-needed //p' "$manifest")"
if [ -n "$need" ] && ! glibc_at_least "$need"; then
  echo "device_run: the device's glibc $have is older than the $need the bundle needs:" \
    "build the bundle on an older distribution" >&2
  exit 4
fi

ldconfig="$(command -v ldconfig || echo /sbin/ldconfig)"  # not on every PATH

# (2) The GL/EGL loaders.
gl_path=""
[ -z "$gl_root" ] && [ "$allow_software" = 1 ] && gl_root="$work/glroot"
if [ -n "$gl_root" ] && [ "$gl_root" != / ]; then
  mkdir -p "$gl_root"
  for f in "$bundle"/gl/*.deb; do dpkg -x "$f" "$gl_root"; done
  gl_path="$(cd "$gl_root" && pwd)/usr/lib/x86_64-linux-gnu"
else
  for f in "$bundle"/gl/*.deb; do dpkg -x "$f" /; done
  "$ldconfig"
fi

# (6, before LD_LIBRARY_PATH: python3 and xz use the device's own libraries) The meshes.
unxz_to() {
  if command -v xz >/dev/null; then
    xz -dc "$1" >"$2"
  else
    python3 -c 'import lzma, shutil, sys; shutil.copyfileobj(lzma.open(sys.argv[1]), open(sys.argv[2], "wb"))' "$1" "$2"
  fi
}
md5_of() { md5sum <"$1" | cut -d' ' -f1; }
meshes="$work/meshes"
mkdir -p "$meshes"
while read -r name md5; do
  target="$meshes/$name"
  [ -f "$target" ] && [ "$(md5_of "$target")" = "$md5" ] && continue
  if [ -f "$bundle/meshes/$name.xz" ]; then
    unxz_to "$bundle/meshes/$name.xz" "$target.tmp"
  elif [ "$name" = armadillo_1m.off ]; then
    # scripts/fetch-bench-meshes.sh's subdivision, read from that script (one copy).
    mesh_start=$SECONDS
    awk '/<<.PYTHON.$/ { inside = 1; next } /^PYTHON$/ { inside = 0 } inside' \
      scripts/fetch-bench-meshes.sh >"$meshes/subdivide.py"
    python3 "$meshes/subdivide.py" "$meshes/armadillo.off" "$target.tmp"
    echo "device_run: armadillo_1m.off made again in $((SECONDS - mesh_start))s"
  else
    echo "device_run: no $name.xz in $bundle/meshes" >&2
    exit 1
  fi
  if [ "$(md5_of "$target.tmp")" != "$md5" ]; then
    echo "device_run: $name differs from the one the figures here used (md5)" >&2
    exit 1
  fi
  mv "$target.tmp" "$target"
done < <(sed -n 's/^mesh-md5 //p' "$manifest")
export MESHES="$meshes"
# bench/pml_cpu_bench.sh reads data/bench/: there it is absent (ignored files do not travel).
if [ ! -e data/bench ]; then
  rm -f data/bench
  mkdir -p data
  ln -s "$meshes" data/bench
fi

# (3) Our binaries' libraries; the bundle's C++ runtime only where the device's is too old
# (a newer libstdc++ serves older binaries, and NVIDIA's libraries may want the newer one).
cxx_need="$(sed -n 's/^glibcxx-needed //p' "$manifest")"
system_cxx="$("$ldconfig" -p | awk '$1 == "libstdc++.so.6" && /x86-64/ && !n++ { print $NF }')"
cxx_path="$bundle/lib/cxx"
if [ "$bundle_cxx" = 0 ] && [ -n "$cxx_need" ] && [ -n "$system_cxx" ] && grep -aqF "GLIBCXX_$cxx_need" "$system_cxx"; then
  cxx_path=""
fi
echo "device_run: C++ runtime: ${cxx_path:-$system_cxx} (GLIBCXX_$cxx_need needed)"
need="$(sed -n 's/^glibc-needed-by-cxx //p' "$manifest")"
if [ -n "$cxx_path" ] && [ -n "$need" ] && ! glibc_at_least "$need"; then
  echo "device_run: the device's libstdc++ lacks GLIBCXX_$cxx_need and its glibc $have is" \
    "older than the $need the bundle's libstdc++ needs" >&2
  exit 4
fi
export LD_LIBRARY_PATH="$bundle/lib${cxx_path:+:$cxx_path}${gl_path:+:$gl_path}${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

# (4) NVIDIA's EGL vendor file, where glvnd's default folders do not list it.
nvidia_vendor=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
if [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ] && [ -f "$nvidia_vendor" ] &&
  ! compgen -G "/usr/share/glvnd/egl_vendor.d/*nvidia*" >/dev/null &&
  ! compgen -G "/etc/glvnd/egl_vendor.d/*nvidia*" >/dev/null; then
  export __EGL_VENDOR_LIBRARY_FILENAMES="$nvidia_vendor"
fi
echo "device_run: EGL vendor files: ${__EGL_VENDOR_LIBRARY_FILENAMES:-the default folders of glvnd}"
# The vendor library itself, where the loader cache does not know it (glvnd dlopens it by name).
nvidia_lib=/usr/local/nvidia/lib64
if ! "$ldconfig" -p | awk '/libEGL_nvidia/ { n++ } END { exit n ? 0 : 1 }' &&
  [ -f "$nvidia_lib/libEGL_nvidia.so.0" ]; then
  export LD_LIBRARY_PATH="$LD_LIBRARY_PATH:$nvidia_lib"
  echo "device_run: libEGL_nvidia from $nvidia_lib (not in the loader cache)"
fi

# (5) The renderer.
info_args=(--rows=64 --repeats=1)
[ "$allow_software" = 1 ] || info_args+=(--no-software)
set +e
info="$("$bundle/build/gpu/mlclust-gpu-info" "${info_args[@]}" 2>&1)"
info_rc=$?
set -e
echo "$info" | tee -a "$out/env.txt"
renderer="$(echo "$info" | sed -n 's/^renderer: *//p' | awk 'NR == 1')"
if [ "$info_rc" != 0 ] || { [ "$allow_software" = 0 ] && ! echo "$renderer" | grep -qi nvidia; }; then
  {
    echo "device_run: no NVIDIA renderer (mlclust-gpu-info exit $info_rc, renderer '${renderer:-none}'):" \
      "no figures taken. What the loader saw:"
    echo "  EGL vendor files: $(find /usr/share/glvnd/egl_vendor.d /etc/glvnd/egl_vendor.d \
      /usr/local/nvidia/share/glvnd/egl_vendor.d -name '*.json' 2>/dev/null | tr '\n' ' ')"
    echo "  libEGL_nvidia: $("$ldconfig" -p | awk '/libEGL_nvidia/ && !n++ { print $NF } END { if (!n) print "not in the ld cache" }')"
    ldd "$bundle/build/gpu/mlclust-gpu-info" | grep -E 'not found|EGL|GL' | sed 's/^/  /'
  } >&2
  exit 3
fi
echo "device_run: renderer $renderer; set-up took $((SECONDS - started))s"

# The threads: the issue's CPU figures are 16-core figures; say so where they are not.
threads="${threads:-$(nproc)}"
if [ "$threads" != 16 ] && [ "$quick" = 0 ]; then
  echo "device_run: WARNING: the CPU rows run on $threads threads (nproc $(nproc)), not the" \
    "16 cores issue 10's figures assume: label them so" | tee -a "$out/env.txt"
fi

# (7) The rows, in priority order, in what is left.
left=$((budget - (SECONDS - started) - 10))
[ "$left" -gt 0 ] || { echo "device_run: no time left for the rows" >&2; exit 5; }
set +e
bash bench/gpu_node.sh --build "$bundle/build" "${node_args[@]}" --threads "$threads" \
  --budget "$left" --out "$out"
rc=$?
set -e
echo "device_run: rows done (exit $rc) after $((SECONDS - started))s of ${budget}s:"
column -t -s $'\t' "$out/gpu_node_status.tsv" 2>/dev/null || cat "$out/gpu_node_status.tsv"
exit "$rc"
