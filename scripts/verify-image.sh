#!/usr/bin/env bash
# Builds docker/Dockerfile's runtime image with podman and checks it for real: the image's
# libraries resolve, the server starts in the container and reaches SERVING on the gRPC
# health service, a client outside the container gets the same labels as an in-process
# run, /metrics answers, TLS + a bearer token work through a mounted volume (and plaintext
# and a wrong token are refused), `podman stop` (SIGTERM) exits 0, and a job running at
# SIGTERM finishes within the drain time while docker/compose.yaml's healthcheck fails.
# The server containers run as docker/k8s/base/deployment.yaml's securityContext asks:
# user 65534, read-only root file system with a /tmp tmpfs, no capabilities.
#
#   bash scripts/install-deps.sh --deploy   # podman, buildah, runc, mmdebstrap, python3-yaml
#   bash scripts/verify-image.sh            # as root
#
# What it does not do: compile inside the image (the Dockerfile's "build" stage; here
# MLCLUST_ARTIFACTS=prebuilt copies the install tree of build-image/, made on this Debian 12
# host) and run on an NVIDIA GPU (no GPU or container toolkit here: the server uses Mesa's
# llvmpipe through the image's EGL).
#
# Made for a host where registries are out of reach and podman runs inside another
# container: the debian:12 base comes from Debian's archive (mmdebstrap, then podman
# import), storage is vfs, RUN steps use chroot isolation, the container runs under runc
# with explicit ulimits (crun refuses cgroup v1 hybrid; raising RLIMIT_NOFILE is not
# permitted). Override with PODMAN, RUNTIME, PORT_GRPC, PORT_METRICS.
set -euo pipefail
cd "$(dirname "$0")/.."

PODMAN=${PODMAN:-podman --storage-driver vfs}
RUNTIME=${RUNTIME:---runtime runc --ulimit nofile=20000:20000 --ulimit nproc=8192:8192}
PORT_GRPC=${PORT_GRPC:-50071}
PORT_METRICS=${PORT_METRICS:-9471}
IMAGE=localhost/mlclust:verify
NAME=mlclust-verify
WORK=$(mktemp -d /tmp/mlclust-verify.XXXXXX)
PY=/usr/bin/python3
failures=0

step() { printf '\n== %s\n' "$*"; }
ok() { printf 'ok: %s\n' "$*"; }
fail() {
  printf 'FAIL: %s\n' "$*"
  failures=$((failures + 1))
}
cleanup() {
  $PODMAN rm -f "$NAME" >/dev/null 2>&1 || true
  rm -rf "$WORK"
}
trap cleanup EXIT

# A grpc.health.v1 probe without generated stubs: HealthCheckRequest{service} is field 1
# (string), the reply's status field 1 (enum, SERVING = 1).
health() {  # health ADDR SERVICE -> prints SERVING / NOT_SERVING / an error
  "$PY" - "$1" "$2" <<'EOF'
import sys, grpc
addr, service = sys.argv[1], sys.argv[2].encode()
call = grpc.insecure_channel(addr).unary_unary("/grpc.health.v1.Health/Check")
try:
    reply = call(b"\x0a" + bytes([len(service)]) + service, timeout=2)
    status = reply[1] if len(reply) >= 2 and reply[0] == 0x08 else 0
    print({1: "SERVING", 2: "NOT_SERVING"}.get(status, "UNKNOWN(%d)" % status))
except grpc.RpcError as e:
    print(e.code().name)
EOF
}

step "build tree (build-image/, the Dockerfile's cmake flags)"
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-/work} CCACHE_NOHASHDIR=true
cmake -S . -B build-image -G Ninja -DCMAKE_BUILD_TYPE=Release -DMLCLUST_BUILD_TESTS=OFF \
  -DMLCLUST_BUILD_BENCH=OFF >/dev/null
cmake --build build-image -j2 --target mlclust
rm -rf docker/prebuilt
cmake --install build-image --prefix docker/prebuilt/opt/mlclust >/dev/null
M=build-image/client/mlclust

step "base image debian:12"
if ! $PODMAN image exists docker.io/library/debian:12; then
  if ! $PODMAN pull docker.io/library/debian:12 2>/dev/null; then
    echo "no registry: debian:12 from Debian's archive (mmdebstrap --variant=minbase)"
    mmdebstrap --variant=minbase --mode=root bookworm "$WORK/debian12.tar" \
      http://deb.debian.org/debian
    $PODMAN import --change 'CMD ["bash"]' "$WORK/debian12.tar" docker.io/library/debian:12
    rm -f "$WORK/debian12.tar"
  fi
fi

step "podman build (MLCLUST_ARTIFACTS=prebuilt)"
$PODMAN build --isolation chroot --pull=never --build-arg MLCLUST_ARTIFACTS=prebuilt \
  -f docker/Dockerfile -t "$IMAGE" .
$PODMAN image inspect "$IMAGE" --format 'image {{.Id}} size {{.Size}} user {{.Config.User}} entrypoint {{.Config.Entrypoint}}'

step "every library of /opt/mlclust/bin/mlclust resolves in the image"
# shellcheck disable=SC2086
ldd_out=$($PODMAN run --rm $RUNTIME --network none --entrypoint /usr/bin/ldd "$IMAGE" \
  /opt/mlclust/bin/mlclust)
if grep -q 'not found' <<<"$ldd_out"; then
  fail "missing libraries: $(grep 'not found' <<<"$ldd_out" | tr '\n' ' ')"
else
  ok "$(wc -l <<<"$ldd_out") libraries, none missing"
fi
# shellcheck disable=SC2086
version=$($PODMAN run --rm $RUNTIME --network none --entrypoint mlclust "$IMAGE" --version)
ok "mlclust --version in the image: $version"

wait_serving() {  # wait_serving ADDR -> 0 when mlclust.v1.Clustering is SERVING
  for _ in $(seq 1 60); do
    [ "$(health "$1" mlclust.v1.Clustering)" = SERVING ] && return 0
    sleep 0.5
  done
  return 1
}

SECURE=(--read-only --tmpfs /tmp --cap-drop ALL --security-opt no-new-privileges
  --user 65534:65534)
# docker/compose.yaml's healthcheck, run inside the container.
HEALTHCHECK="exec 3<>/dev/tcp/127.0.0.1/9464 && printf 'GET /metrics HTTP/1.0\r\nHost: localhost\r\n\r\n' >&3 && grep -q '^mlclust_draining 0' <&3"

step "plaintext server in the container, client outside"
$PODMAN rm -f "$NAME" >/dev/null 2>&1 || true
# shellcheck disable=SC2086
$PODMAN run -d --name "$NAME" $RUNTIME "${SECURE[@]}" -p "127.0.0.1:$PORT_GRPC:50051" \
  -p "127.0.0.1:$PORT_METRICS:9464" "$IMAGE" --metrics 0.0.0.0:9464 --workers 1 >/dev/null
if wait_serving "127.0.0.1:$PORT_GRPC"; then
  ok "health mlclust.v1.Clustering: SERVING; overall: $(health "127.0.0.1:$PORT_GRPC" '')"
else
  fail "never SERVING"
  $PODMAN logs "$NAME" || true
fi
$PODMAN logs "$NAME" 2>&1 | sed 's/^/  container: /'
"$M" mesh data/fandisk.off --server "127.0.0.1:$PORT_GRPC" --clusters 20 \
  --labels "$WORK/container.txt"
"$M" mesh data/fandisk.off --clusters 20 --labels "$WORK/inprocess.txt"
if cmp -s "$WORK/container.txt" "$WORK/inprocess.txt"; then
  ok "fandisk ML, 20 clusters: container labels identical to in-process ($(wc -l <"$WORK/container.txt") faces)"
else
  fail "container labels differ from in-process"
fi
"$PY" -c 'import numpy as np; np.save("'"$WORK"'/points.npy", np.random.default_rng(7).normal(size=(20000, 3)).astype(np.float32))'
"$M" points "$WORK/points.npy" --server "127.0.0.1:$PORT_GRPC" --clusters 8 \
  --labels "$WORK/points-container.txt" || fail "points job in the container"
"$M" points "$WORK/points.npy" --clusters 8 --labels "$WORK/points-inprocess.txt" || true
if cmp -s "$WORK/points-container.txt" "$WORK/points-inprocess.txt"; then
  ok "20,000 points, 8 clusters: container labels identical to in-process"
else
  fail "points labels differ (or a points job failed)"
fi
metrics=$(curl -s "http://127.0.0.1:$PORT_METRICS/metrics")
grep -E '^mlclust_(queue_depth|queue_capacity|jobs_accepted_total|jobs_ended_total|gpu_available|device_info|draining) ' \
  <<<"$(sed 's/{[^}]*}/ &/' <<<"$metrics")" | sed 's/^/  metrics: /' || true
if grep -q '^mlclust_jobs_accepted_total 2$' <<<"$metrics" &&
  grep -q '^mlclust_queue_depth 0$' <<<"$metrics"; then
  ok "/metrics: 2 jobs accepted, queue depth 0"
else
  fail "/metrics counts"
fi
if $PODMAN exec "$NAME" bash -c "$HEALTHCHECK"; then
  ok "compose healthcheck passes while serving"
else
  fail "compose healthcheck fails while serving"
fi
start=$(date +%s.%N)
$PODMAN stop -t 35 "$NAME" >/dev/null
stopped=$(date +%s.%N)
code=$($PODMAN inspect "$NAME" --format '{{.State.ExitCode}}')
$PODMAN logs "$NAME" 2>&1 | tail -3 | sed 's/^/  container: /'
if [ "$code" = 0 ]; then
  ok "podman stop (SIGTERM): exit 0 after $(awk "BEGIN{printf \"%.1f\", $stopped - $start}") s"
else
  fail "exit code $code after SIGTERM"
fi
$PODMAN rm -f "$NAME" >/dev/null

step "SIGTERM with a job running (armadillo_1m, 832,000 faces, ML): drain"
# The job takes 20-30 s on this shared machine: --drain-seconds 60 (the last one given
# wins over the entrypoint's 25) so that load cannot make the drain time run out.
# shellcheck disable=SC2086
$PODMAN run -d --name "$NAME" $RUNTIME "${SECURE[@]}" -p "127.0.0.1:$PORT_GRPC:50051" "$IMAGE" \
  --metrics 0.0.0.0:9464 --drain-seconds 60 >/dev/null
wait_serving "127.0.0.1:$PORT_GRPC" || fail "never SERVING"
"$M" mesh data/bench/armadillo_1m.off --server "127.0.0.1:$PORT_GRPC" --clusters 100 \
  --labels "$WORK/drain.txt" >"$WORK/drain.log" 2>&1 &
client=$!
sleep 6
start=$(date +%s.%N)
$PODMAN kill -s TERM "$NAME" >/dev/null
sleep 1
if $PODMAN exec "$NAME" bash -c "$HEALTHCHECK" 2>/dev/null; then
  fail "compose healthcheck still passes while draining"
else
  ok "compose healthcheck fails while draining"
fi
$PODMAN wait "$NAME" >/dev/null
stopped=$(date +%s.%N)
code=$($PODMAN inspect "$NAME" --format '{{.State.ExitCode}}')
if wait "$client" && [ "$(wc -l <"$WORK/drain.txt")" = 832000 ] && [ "$code" = 0 ]; then
  ok "the running job finished during the drain ($(tail -1 "$WORK/drain.log")); server exit 0 $(awk "BEGIN{printf \"%.1f\", $stopped - $start}") s after SIGTERM"
else
  fail "drain: client $(tail -1 "$WORK/drain.log"), exit code $code"
fi
$PODMAN logs "$NAME" 2>&1 | tail -4 | sed 's/^/  container: /'
$PODMAN rm -f "$NAME" >/dev/null

step "TLS + bearer token from a mounted volume"
mkdir -p "$WORK/secrets"
openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=localhost \
  -addext 'subjectAltName=DNS:localhost,IP:127.0.0.1' \
  -keyout "$WORK/secrets/tls.key" -out "$WORK/secrets/tls.crt" 2>/dev/null
printf 'verify-token-%s tenant-a\n' "$RANDOM$RANDOM" >"$WORK/secrets/tokens"
printf 'wrong-token\n' >"$WORK/wrong-token"
# The container runs as nobody: the mounted files must be readable by it.
chmod 0755 "$WORK/secrets"
chmod 0644 "$WORK/secrets/"*
# shellcheck disable=SC2086
$PODMAN run -d --name "$NAME" $RUNTIME "${SECURE[@]}" -p "127.0.0.1:$PORT_GRPC:50051" \
  -v "$WORK/secrets:/run/secrets/mlclust:ro" "$IMAGE" \
  --tls-cert /run/secrets/mlclust/tls.crt --tls-key /run/secrets/mlclust/tls.key \
  --auth-token-file /run/secrets/mlclust/tokens >/dev/null
sleep 3
$PODMAN logs "$NAME" 2>&1 | sed 's/^/  container: /'
tls=(--server "localhost:$PORT_GRPC" --tls-ca "$WORK/secrets/tls.crt")
if "$M" mesh data/fandisk.off "${tls[@]}" --auth-token-file "$WORK/secrets/tokens" \
  --clusters 20 --labels "$WORK/tls.txt" && cmp -s "$WORK/tls.txt" "$WORK/inprocess.txt"; then
  ok "TLS + token: job ran, labels identical"
else
  fail "TLS + token job"
fi
if out=$("$M" stats "${tls[@]}" --auth-token-file "$WORK/wrong-token" 2>&1); then
  fail "a wrong token was accepted"
else
  ok "wrong token refused: $(tail -1 <<<"$out")"
fi
if out=$("$M" stats --server "127.0.0.1:$PORT_GRPC" 2>&1); then
  fail "plaintext was accepted by the TLS server"
else
  ok "plaintext refused: $(tail -1 <<<"$out")"
fi
$PODMAN stop -t 35 "$NAME" >/dev/null
$PODMAN rm -f "$NAME" >/dev/null

printf '\n%s\n' "$([ "$failures" = 0 ] && echo 'verify-image: all checks passed' ||
  echo "verify-image: $failures check(s) FAILED")"
[ "$failures" = 0 ]
