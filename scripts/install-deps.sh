#!/usr/bin/env bash
# Installs everything mlclust needs to build, test and benchmark, from Debian 12's archive.
# Idempotent: packages already present are left alone. Run as root (or with sudo).
set -euo pipefail

packages=(
  build-essential cmake pkg-config ninja-build
  # wire + service
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  # library support
  libabsl-dev libdraco-dev libassimp-dev libtbb-dev
  # JSON for rewriting Draco-compressed glTF (core/io/gltf_draco.cc; header only)
  nlohmann-json3-dev
  # headless GL: EGL + Mesa (llvmpipe where there is no GPU)
  libegl-dev libegl1 libgl1-mesa-dri libopengl-dev libgl-dev
  # the Python package (python/): Debian's python3 with gRPC, protobuf and numpy; the
  # stubs are generated with protoc and grpc_python_plugin (protobuf-compiler-grpc)
  python3 python3-grpcio python3-protobuf python3-numpy
  # its install (python/setup.py: `pip install --no-build-isolation ./python` into a venv)
  # and its estimators' tests (scikit-learn's conventions and estimator checks)
  python3-pip python3-venv python3-setuptools python3-wheel python3-sklearn
  # the --plot PNG (client/plot.h): cairo, and a font for its labels
  libcairo2-dev fonts-dejavu-core
  # the --preview PNG (gpu/render/png_codec.h)
  libpng-dev
  # the upload's CRC-32 (JobSpec.input_crc32; server and client)
  zlib1g-dev
  # tests; draco's draco_encoder makes the foreign payloads of tests/e2e/draco_encoder_test.sh
  libgtest-dev libgmock-dev draco
  # TLS tests make their certificates at test time (tests/e2e/tls_test.cc)
  openssl
  # the server's Prometheus endpoint (serve --metrics; server/metrics.h)
  libcpp-httplib-dev
  # the libFuzzer targets (fuzz/, scripts/fuzz-smoke.sh): clang-14 with libFuzzer
  clang-14 libclang-rt-14-dev
  # habits checked in CI: formatting (scripts/check-format.sh), lint (.clang-tidy)
  clang-format clang-tidy
  # CI checks the compose file and Kubernetes manifests (scripts/check-deploy.py)
  python3-yaml
  # the CLI's option parser (client/cli.cc; header only)
  libcli11-dev
  # meshlet bounds and normal cones (core/meshlets: meshopt_computeMeshletBounds; 0.18)
  libmeshoptimizer-dev
)

if [ "${1:-}" = "--deploy" ]; then
  # scripts/verify-image.sh (podman build and run of docker/Dockerfile, debian:12 from
  # Debian's archive where no registry answers); check-deploy.py's python3-yaml is above
  packages+=(podman buildah runc mmdebstrap)
fi

if [ "${1:-}" = "--bench" ]; then
  # peers and plotting for bench/ (CGAL VSA, scikit-learn, fastcluster, faiss, matplotlib;
  # the Python peers run under Debian's /usr/bin/python3)
  packages+=(libcgal-dev libcgal-demo python3-numpy python3-matplotlib
             python3-sklearn python3-fastcluster python3-faiss)
  # the meshlet peers of bench/peers/meshlets_bench.cc and meshlets_caps_bench.cc:
  # meshopt_buildMeshlets (libmeshoptimizer-dev, above) and METIS k-way
  packages+=(libmetis-dev)
fi

# The Node example and its test (examples/node, tests/e2e/node_client_test.sh): Debian 12's
# nodejs 18 and npm 9, unless a node with its own npm is there already.
if ! command -v node > /dev/null || ! command -v npm > /dev/null; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
