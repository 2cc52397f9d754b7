#!/usr/bin/env bash
# Packs what bench/gpu_node.sh needs on the device machine (an NVIDIA GPU node with none of
# this machine's Debian libraries and no network) into one ignored folder, .devbundle/,
# that a device call carries (`carry: [".devbundle"]`); bench/device_run.sh unpacks and
# uses it there. CONTRIBUTING.md, "GPU-node figures", has the whole procedure.
#
#   bash bench/device_bundle.sh [--build DIR] [--out DIR] [--no-build]
#   bash bench/device_bundle.sh --check [--out DIR]    # is the bundle complete? (no build)
#
# The folder holds, mirroring the build tree so that gpu_node.sh takes it as --build:
#   build/bench/*, build/gpu/mlclust-gpu-info   the binaries gpu_node.sh --list-binaries
#                                               names (those that exist), stripped
#   lib/       every shared library `ldd` lists for them, except glibc's own (libc, libm,
#              libdl, libpthread, librt, ld-linux, ...: the device's glibc is newer) and
#              the GL/EGL loaders (libEGL, libGL, libOpenGL, libGLdispatch, libGLX,
#              libGLES*: they come from gl/); the C++ runtime (libstdc++, libgcc_s) in
#              lib/cxx/, used there only where the device's own is older than it needs
#   gl/        the loaders as Debian amd64 .debs (libegl1 libglvnd0 libopengl0 libgl1
#              libglx0 libgles2), for `dpkg -x` there (/work/.library/device/README.md)
#   meshes/    fandisk, bunny00 and armadillo as .off.xz; armadillo_1m (30 MB) is made
#              there again by scripts/fetch-bench-meshes.sh's subdivision (its Python
#              imports only sys, so the device's python3 runs it); its md5 is in MANIFEST
#   MANIFEST   commit, date, files, md5s, the newest GLIBC and GLIBCXX symbol versions the
#              binaries and libraries ask for, and the C++ runtime's own GLIBC need apart
#              (device_run.sh checks them against the device's)
# and prints the total size. Exits non-zero if the bundle and the tree that travels with
# it (tracked and untracked-not-ignored files) exceed 64 MiB, the device call's limit,
# less DEVBUNDLE_MARGIN_MIB (default 2) for what the call adds.
#
# Builds what is missing first (Release: scripts/build.sh when build/ is not configured,
# else only the binaries' targets, -j${JOBS:-2}); --no-build takes the build as it is.
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"

build_dir=build out=.devbundle check=0 do_build=1
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build_dir="${2:?}"; shift 2 ;;
    --out) out="${2:?}"; shift 2 ;;
    --check) check=1; shift ;;
    --no-build) do_build=0; shift ;;
    -h | --help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
    *) echo "device_bundle: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
readonly limit_bytes=$((64 * 1024 * 1024))
readonly margin_bytes=$((${DEVBUNDLE_MARGIN_MIB:-2} * 1024 * 1024))
readonly meshes=(fandisk bunny00 armadillo)
readonly gl_debs=(libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
# glibc's own libraries and the GL/EGL loaders: never bundled.
readonly skip_re='^(libc|libm|libdl|libpthread|librt|libresolv|libutil|libanl|libmvec|libnsl|libBrokenLocale|libthread_db|ld-linux-x86-64|ld-linux|linux-vdso|libEGL|libGL|libOpenGL|libGLdispatch|libGLX|libGLES[A-Za-z0-9_]*)\.so'

die() { echo "device_bundle: $*" >&2; exit 1; }

# What travels besides the bundle: tracked and untracked-not-ignored files.
tree_bytes() {
  git ls-files -z --cached --others --exclude-standard |
    xargs -0 -r stat -L -c %s 2>/dev/null | awk '{ s += $1 } END { print s + 0 }'
}

size_report() {
  local bundle tree total
  bundle="$(du -sb "$out" | cut -f1)"
  tree="$(tree_bytes)"
  total=$((bundle + tree))
  awk -v b="$bundle" -v t="$tree" -v m="$margin_bytes" 'BEGIN {
    printf "device_bundle: bundle %.1f MiB + tree %.1f MiB = %.1f MiB of 64 MiB (margin %d MiB)\n",
      b / 1048576, t / 1048576, (b + t) / 1048576, m / 1048576 }'
  [ "$total" -le $((limit_bytes - margin_bytes)) ] ||
    die "too large for one device call: $total bytes (limit $limit_bytes less the margin)"
}

# --check: every file of MANIFEST is there with its md5, and every library the binaries
# need resolves from lib/, the loaders' .debs, or glibc.
check_bundle() {
  [ -f "$out/MANIFEST" ] || die "$out/MANIFEST missing: run bench/device_bundle.sh"
  local bad=0 line md5 file
  while read -r line; do
    md5="${line%% *}" file="${line#*  }"
    if [ ! -f "$out/$file" ] || [ "$(md5sum <"$out/$file" | cut -d' ' -f1)" != "$md5" ]; then
      echo "device_bundle: $out/$file missing or changed" >&2
      bad=1
    fi
  done < <(sed -n 's/^file //p' "$out/MANIFEST")
  for deb in "${gl_debs[@]}"; do
    compgen -G "$out/gl/${deb}_*.deb" >/dev/null || { echo "device_bundle: no $deb .deb" >&2; bad=1; }
  done
  # Nothing beside what the manifest lists (unpacked meshes would not travel: 64 MiB).
  local extra
  extra="$(cd "$out" && find . -type f ! -name MANIFEST | sed 's|^\./||' | sort |
    comm -23 - <(sed -n 's/^file [0-9a-f]*  //p' MANIFEST | sort))"
  if [ -n "$extra" ]; then
    echo "device_bundle: files in $out that MANIFEST does not list: $(tr "\n" " " <<<"$extra")" >&2
    bad=1
  fi
  local binary unresolved
  for binary in "$out"/build/bench/* "$out"/build/gpu/*; do
    [ -f "$binary" ] || continue
    unresolved="$(LD_LIBRARY_PATH="$out/lib:$out/lib/cxx" ldd "$binary" | awk -v re="$skip_re" -v lib="$out/lib/" '
      /=>/ { name = $1; path = $3
             if (name ~ re) next
             if (path == "not" || index(path, lib) != 1) print name " -> " path }')"
    if [ -n "$unresolved" ]; then
      echo "device_bundle: $binary takes libraries from outside $out/lib:" >&2
      printf '  %s\n' "$unresolved" >&2
      bad=1
    fi
  done
  [ "$bad" = 0 ] || die "$out is incomplete"
  echo "device_bundle: $out complete ($(grep -c '^file ' "$out/MANIFEST") files)"
  size_report
}

if [ "$check" = 1 ]; then
  check_bundle
  exit 0
fi

# --- 1. The binaries ------------------------------------------------------------------
mapfile -t wanted < <(bash bench/gpu_node.sh --list-binaries)
if [ "$do_build" = 1 ]; then
  if [ ! -f "$build_dir/CMakeCache.txt" ]; then
    [ "$build_dir" = build ] || die "$build_dir is not configured"
    bash scripts/build.sh
  fi
  grep -q '^CMAKE_BUILD_TYPE:STRING=Release$' "$build_dir/CMakeCache.txt" ||
    die "$build_dir is not a Release build (figures from it would mislead)"
  ! grep -q 'march=native' "$build_dir/CMakeCache.txt" ||
    die "$build_dir is built with -march=native: its binaries may not run on the device's CPU"
  mapfile -t known < <(cmake --build "$build_dir" --target help 2>/dev/null |
    sed -n 's/^\([A-Za-z0-9_.-]*\): .*/\1/p')
  targets=()
  for binary in "${wanted[@]}"; do
    for target in "${known[@]}"; do
      [ "$target" = "$(basename "$binary")" ] && targets+=("$target")
    done
  done
  [ "${#targets[@]}" -gt 0 ] && cmake --build "$build_dir" --target "${targets[@]}" \
    --parallel "${JOBS:-2}"
fi
rm -rf "$out.tmp"
mkdir -p "$out.tmp/build/bench" "$out.tmp/build/gpu" "$out.tmp/lib" "$out.tmp/meshes"
binaries=()
for binary in "${wanted[@]}"; do
  if [ -x "$build_dir/$binary" ]; then
    strip --strip-all -o "$out.tmp/build/$binary" "$build_dir/$binary"
    binaries+=("$build_dir/$binary")
  else
    echo "device_bundle: $build_dir/$binary not built here (its rows will be skipped there)"
  fi
done
[ -x "$out.tmp/build/bench/gpu_stages_bench" ] || die "no gpu_stages_bench in $build_dir"
[ -x "$out.tmp/build/gpu/mlclust-gpu-info" ] || die "no gpu/mlclust-gpu-info in $build_dir"

# --- 2. Their libraries -----------------------------------------------------------------
mapfile -t libraries < <(ldd "${binaries[@]}" | awk -v re="$skip_re" '
  /not found/ { print "MISSING " $1; next }
  /=>/ && $3 ~ /^\// { if ($1 !~ re) print $1 " " $3 }' | sort -u)
for entry in "${libraries[@]}"; do
  name="${entry%% *}" path="${entry#* }"
  [ "$name" = MISSING ] && die "a binary needs $path, which is not found here"
  # The C++ runtime apart: device_run.sh takes the device's own where it is new enough.
  case "$name" in libstdc++.so.* | libgcc_s.so.*) dir=lib/cxx ;; *) dir=lib ;; esac
  mkdir -p "$out.tmp/$dir"
  strip --strip-unneeded -o "$out.tmp/$dir/$name" "$(readlink -f "$path")"
done

# --- 3. The GL/EGL loaders as .debs (kept from an earlier bundle: they do not change) ----
mkdir -p "$out.tmp/gl"
if compgen -G "$out/gl/*.deb" >/dev/null; then cp "$out"/gl/*.deb "$out.tmp/gl/"; fi
missing=()
for deb in "${gl_debs[@]}"; do
  compgen -G "$out.tmp/gl/${deb}_*.deb" >/dev/null || missing+=("$deb")
done
if [ "${#missing[@]}" -gt 0 ]; then
  apt_options=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64
    -oDir::State::Lists=/tmp/amd64)
  mkdir -p /tmp/amd64/partial
  apt-get "${apt_options[@]}" update >/dev/null
  (cd "$out.tmp/gl" && apt-get "${apt_options[@]}" download "${missing[@]}")
fi

# --- 4. The meshes ------------------------------------------------------------------------
for mesh in "${meshes[@]}"; do
  [ -f "data/bench/$mesh.off" ] || die "data/bench/$mesh.off missing: scripts/fetch-bench-meshes.sh"
  xz -6 -T1 -c "data/bench/$mesh.off" >"$out.tmp/meshes/$mesh.off.xz"
done
[ -f data/bench/armadillo_1m.off ] ||
  die "data/bench/armadillo_1m.off missing: scripts/fetch-bench-meshes.sh (its md5 is checked there)"

# --- 5. The manifest ----------------------------------------------------------------------
# The symbol versions asked for (the C++ runtime's own definitions are not asks: objdump
# marks undefined symbols *UND*).
# The C++ runtime's own glibc need apart: it is used there only where the device's is older.
symbols="$(find "$out.tmp/build" "$out.tmp/lib" -path "$out.tmp/lib/cxx" -prune -o -type f \
  -exec objdump -T {} + 2>/dev/null)"
glibc="$(grep -o 'GLIBC_[0-9.]*' <<<"$symbols" | sort -Vu | tail -1)"
glibcxx="$(grep '\*UND\*' <<<"$symbols" | grep -o 'GLIBCXX_[0-9.]*' | sort -Vu | tail -1)"
glibc_cxx="$(find "$out.tmp/lib/cxx" -type f -exec objdump -T {} + 2>/dev/null |
  grep -o 'GLIBC_[0-9.]*' | sort -Vu | tail -1)"
{
  echo "commit $(git rev-parse HEAD)$(git diff --quiet HEAD -- . ':!data' || echo '+changes')"
  echo "date $(date -u +%FT%TZ)"
  # shellcheck disable=SC1091
  echo "built-on $(. /etc/os-release && echo "$ID-$VERSION_ID") $(uname -m)"
  echo "glibc-needed ${glibc#GLIBC_}"
  echo "glibcxx-needed ${glibcxx#GLIBCXX_}"
  echo "glibc-needed-by-cxx ${glibc_cxx#GLIBC_}"
  for mesh in "${meshes[@]}" armadillo_1m; do
    echo "mesh-md5 $mesh.off $(md5sum <"data/bench/$mesh.off" | cut -d' ' -f1)"
  done
  (cd "$out.tmp" && find build lib gl meshes -type f | sort | xargs md5sum | sed 's/^/file /')
} >"$out.tmp/MANIFEST"
rm -rf "$out"
mv "$out.tmp" "$out"
echo "device_bundle: $out: $(find "$out/build" -type f | wc -l) binaries," \
  "$(find "$out/lib" -type f | wc -l) libraries, $(find "$out/gl" -type f | wc -l) .debs," \
  "$(find "$out/meshes" -type f | wc -l) meshes; glibc ${glibc#GLIBC_} or newer needed there"
# Rows the bundled binaries would skip (a mode or flag of later work not in this build):
# better known here than after a device call.
bash bench/gpu_node.sh --check-guards --build "$out/build" |
  sed 's/^gpu_node: row/device_bundle: WARNING: row/; s/^gpu_node:/device_bundle:/'
size_report
