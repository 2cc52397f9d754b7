#!/usr/bin/python3
"""Checks docker/compose.yaml and the Kubernetes manifests in docker/k8s/ without a cluster.

  /usr/bin/python3 scripts/check-deploy.py [--mlclust build-image/client/mlclust]

Needs python3-yaml (scripts/install-deps.sh); kubectl is used where present. CI (.ci/run)
runs it with --mlclust build/client/mlclust; it takes about a second.

What it checks (no kubeconform or API server here, so no full schema validation):
- every file parses as YAML (python3-yaml); `kubectl kustomize` renders docker/k8s/base
  and docker/k8s/tls (the latter with empty stand-in secret files) when kubectl exists;
- each object has apiVersion, kind, metadata.name, and the fields its kind needs;
- cross references: Deployment selector vs. pod labels, Service/PDB selectors, probe and
  Service target ports vs. container ports, HPA target, Secret names, one probe handler;
- the Deployment asks for a GPU (requests/limits nvidia.com/gpu, runtimeClassName,
  tolerations, nodeSelector), NVIDIA_DRIVER_CAPABILITIES includes graphics, the pull
  policy works for a local image, memory request = limit, and the memory arithmetic of
  deployment.yaml holds for the args actually given;
- readiness asks for mlclust.v1.Clustering, liveness for the overall service, and the
  preStop hook drains (SIGTERM to PID 1, waiting for it to end);
- the metric the HPA scales on is one the server exports (server/*.cc);
- every `mlclust serve` flag in the Deployment and compose file is one `mlclust help
  serve` lists, and with --mlclust the server really starts with the Deployment's args.
"""

import argparse
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
errors = []


def check(cond, what):
    if cond:
        print("ok:", what)
    else:
        print("FAIL:", what)
        errors.append(what)


def load_all(path):
    with open(path) as f:
        return [d for d in yaml.safe_load_all(f) if d is not None]


def mib(quantity):
    m = re.fullmatch(r"(\d+)(Mi|Gi)", str(quantity))
    if not m:
        raise ValueError("memory quantity %r" % quantity)
    return int(m.group(1)) * (1024 if m.group(2) == "Gi" else 1)


def flag_values(args):
    out = {}
    for a in args:
        m = re.fullmatch(r"--([a-z0-9-]+)(?:=(.*))?", a)
        if m:
            out[m.group(1)] = m.group(2)
    return out


def render(kustomize_dir):
    if not shutil.which("kubectl"):
        return None
    r = subprocess.run(["kubectl", "kustomize", kustomize_dir], capture_output=True, text=True)
    check(r.returncode == 0, "kubectl kustomize %s renders" % os.path.relpath(kustomize_dir, ROOT)
          + ("" if r.returncode == 0 else ": " + r.stderr.strip()))
    return [d for d in yaml.safe_load_all(r.stdout) if d] if r.returncode == 0 else None


def check_objects(objs, label, serve_flags, server_metrics):
    by_kind = {}
    for o in objs:
        check(all(k in o for k in ("apiVersion", "kind")) and o.get("metadata", {}).get("name"),
              "%s: %s has apiVersion, kind, metadata.name" % (label, o.get("kind")))
        by_kind.setdefault(o["kind"], []).append(o)
    deployments = by_kind.get("Deployment", [])
    check(len(deployments) == 1, "%s: one Deployment" % label)
    if not deployments:
        return
    d = deployments[0]
    pod = d["spec"]["template"]
    labels = pod["metadata"]["labels"]
    sel = d["spec"]["selector"]["matchLabels"]
    check(sel.items() <= labels.items(), "%s: Deployment selector matches its pod labels" % label)
    spec = pod["spec"]
    check(spec.get("runtimeClassName") == "nvidia", "%s: runtimeClassName nvidia" % label)
    check(any(t.get("key") == "nvidia.com/gpu" for t in spec.get("tolerations", [])),
          "%s: tolerates nvidia.com/gpu taints" % label)
    check(bool(spec.get("nodeSelector")), "%s: nodeSelector for GPU nodes" % label)
    c = spec["containers"][0]
    check(c.get("imagePullPolicy") in ("IfNotPresent", "Never"),
          "%s: imagePullPolicy %s works for a locally built image" % (label, c.get("imagePullPolicy")))
    res = c["resources"]
    check(str(res["limits"].get("nvidia.com/gpu")) == "1" and
          str(res["requests"].get("nvidia.com/gpu")) == "1", "%s: one nvidia.com/gpu" % label)
    check(res["requests"]["memory"] == res["limits"]["memory"],
          "%s: memory request = limit (%s)" % (label, res["limits"]["memory"]))
    env = {e["name"]: e.get("value", "") for e in c.get("env", [])}
    check("graphics" in env.get("NVIDIA_DRIVER_CAPABILITIES", "").split(","),
          "%s: NVIDIA_DRIVER_CAPABILITIES includes graphics" % label)
    ports = {p["name"]: p["containerPort"] for p in c["ports"]}
    for name in ("startupProbe", "readinessProbe", "livenessProbe"):
        probe = c.get(name)
        check(probe is not None, "%s: %s present" % (label, name))
        if probe is None:
            continue
        handlers = [h for h in ("grpc", "httpGet", "tcpSocket", "exec") if h in probe]
        check(len(handlers) == 1, "%s: %s has one handler (%s)" % (label, name, handlers))
        port = probe[handlers[0]].get("port") if handlers and handlers[0] != "exec" else None
        check(port in ports or port in ports.values(),
              "%s: %s port %s is a container port" % (label, name, port))
        if handlers and handlers[0] == "grpc" and "service" in probe["grpc"]:
            check(probe["grpc"]["service"] == "mlclust.v1.Clustering",
                  "%s: %s asks the health service for mlclust.v1.Clustering" % (label, name))
    # Readiness follows the server's state (mlclust.v1.Clustering: device ready, queue not
    # full, not draining); liveness only a hung process (the overall service ""); the
    # preStop hook drains (SIGTERM to the server, waiting for it to end).
    ready = c.get("readinessProbe", {})
    check(ready.get("grpc", {}).get("service") == "mlclust.v1.Clustering" or
          ready.get("httpGet", {}).get("path") == "/ready",
          "%s: readiness asks for mlclust.v1.Clustering or GET /ready (queue full, draining)"
          % label)
    live = c.get("livenessProbe", {})
    check(("grpc" in live and "service" not in live["grpc"]) or "tcpSocket" in live,
          "%s: liveness asks for the overall service or the port (a hung process only)" % label)
    pre_stop = " ".join(c.get("lifecycle", {}).get("preStop", {}).get("exec", {})
                        .get("command", []))
    check("kill -TERM 1" in pre_stop and "kill -0 1" in pre_stop,
          "%s: the preStop hook drains the server and waits for it" % label)
    grace = spec.get("terminationGracePeriodSeconds", 30)
    check(grace > 25, "%s: terminationGracePeriodSeconds %s > the image's --drain-seconds 25"
          % (label, grace))
    live = c.get("livenessProbe", {})
    check(live.get("periodSeconds", 10) * live.get("failureThreshold", 3) > 25,
          "%s: liveness tolerates a 25 s drain" % label)
    # Flags and the memory arithmetic of deployment.yaml's comment.
    flags = flag_values(c["args"])
    unknown = [f for f in flags if f not in serve_flags]
    check(not unknown, "%s: every serve flag is known to `mlclust help serve` %s"
          % (label, unknown or ""))
    need = (3 * 41 * int(flags["max-input-mb"]) + int(flags["max-queued-mb"]) +
            int(flags["max-upload-mb"]) + int(flags["result-total-mb"]) +
            int(flags["kept-results-mb"]) + 512)
    check(int(flags["workers"]) == 2, "%s: --workers 2 (3 jobs at once, as the arithmetic says)"
          % label)
    check(need <= mib(res["limits"]["memory"]),
          "%s: memory %d MiB needed <= limit %s" % (label, need, res["limits"]["memory"]))
    # Volumes: secrets exist, mounts name volumes.
    volumes = {v["name"]: v for v in spec.get("volumes", [])}
    for m in c.get("volumeMounts", []):
        check(m["name"] in volumes, "%s: volumeMount %s names a volume" % (label, m["name"]))
    secrets = {s["metadata"]["name"] for s in by_kind.get("Secret", [])}
    for v in volumes.values():
        if "secret" in v:
            check(v["secret"]["secretName"] in secrets,
                  "%s: Secret %s is defined" % (label, v["secret"]["secretName"]))
    if any("secret" in v for v in volumes.values()):
        for f in ("tls-cert", "tls-key", "auth-token-file"):
            check(f in flags, "%s: --%s given with the Secret mounted" % (label, f))
    for s in by_kind.get("Service", []):
        check(s["spec"].get("clusterIP") == "None", "%s: Service %s is headless"
              % (label, s["metadata"]["name"]))
        check(s["spec"]["selector"].items() <= labels.items(),
              "%s: Service selector matches the pods" % label)
        for p in s["spec"]["ports"]:
            check(p["targetPort"] in ports or p["targetPort"] in ports.values(),
                  "%s: Service port %s targets a container port" % (label, p["name"]))
    for p in by_kind.get("PodDisruptionBudget", []):
        check(p["spec"]["selector"]["matchLabels"].items() <= labels.items() and
              ("maxUnavailable" in p["spec"] or "minAvailable" in p["spec"]),
              "%s: PodDisruptionBudget selects the pods and bounds them" % label)
    hpas = by_kind.get("HorizontalPodAutoscaler", [])
    check(len(hpas) == 1, "%s: one HorizontalPodAutoscaler" % label)
    for h in hpas:
        t = h["spec"]["scaleTargetRef"]
        check(t["kind"] == "Deployment" and t["name"] == d["metadata"]["name"],
              "%s: HPA targets the Deployment" % label)
        for m in h["spec"]["metrics"]:
            name = m["pods"]["metric"]["name"]
            check(name in server_metrics, "%s: HPA metric %s is exported by the server"
                  % (label, name))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mlclust", help="an mlclust binary: start it with the Deployment's args")
    opts = ap.parse_args()

    files = [os.path.join(ROOT, "docker/compose.yaml")] + sorted(
        glob.glob(os.path.join(ROOT, "docker/k8s/**/*.yaml"), recursive=True))
    docs = {}
    for f in files:
        try:
            docs[f] = load_all(f)
            check(True, "%s parses (%d documents)" % (os.path.relpath(f, ROOT), len(docs[f])))
        except yaml.YAMLError as e:
            check(False, "%s parses: %s" % (os.path.relpath(f, ROOT), e))

    server_src = "".join(open(p).read() for p in glob.glob(os.path.join(ROOT, "server/*.cc")))
    server_metrics = set(re.findall(r'"(mlclust_[a-z_]+)"', server_src))
    mlclust = opts.mlclust or os.path.join(ROOT, "build-image/client/mlclust")
    serve_flags = None
    if os.path.exists(mlclust):
        h = subprocess.run([mlclust, "help", "serve"], capture_output=True, text=True)
        serve_flags = set(re.findall(r"--([a-z0-9-]+)", h.stdout + h.stderr))
    else:
        print("note: no mlclust binary at %s: serve flags not checked" % mlclust)
        serve_flags = None

    # The adapter rule names the metric the HPA uses.
    rules = docs.get(os.path.join(ROOT, "docker/k8s/prometheus-adapter-rules.yaml"), [{}])[0]
    rule_names = {r["name"]["as"] for r in rules.get("rules", [])}
    check("mlclust_queue_depth" in rule_names and "mlclust_queue_depth" in server_metrics,
          "prometheus-adapter rule serves mlclust_queue_depth, a gauge of server/server.cc")

    # Compose.
    compose = docs[os.path.join(ROOT, "docker/compose.yaml")][0]
    svc = compose["services"]["mlclust"]
    devs = svc["deploy"]["resources"]["reservations"]["devices"]
    check(any("gpu" in dv.get("capabilities", []) for dv in devs),
          "compose: GPU reservation with capabilities [gpu]")
    check("graphics" in svc["environment"]["NVIDIA_DRIVER_CAPABILITIES"].split(","),
          "compose: NVIDIA_DRIVER_CAPABILITIES includes graphics")
    check(any(str(p).endswith(":50051") for p in svc["ports"]) and
          any(str(p).endswith(":9464") for p in svc["ports"]), "compose: gRPC and metrics ports")
    check(svc["healthcheck"]["test"][0] == "CMD", "compose: healthcheck")
    check(any(v.endswith(":/run/secrets/mlclust:ro") for v in svc["volumes"]),
          "compose: TLS/token volume mounted read-only")
    cflags = flag_values(svc["command"])
    if serve_flags is not None:
        unknown = [f for f in cflags if f not in serve_flags]
        check(not unknown, "compose: every serve flag is known %s" % (unknown or ""))
    check(all(f in cflags for f in ("tls-cert", "tls-key", "auth-token-file")),
          "compose: TLS and tokens on (it listens on every address)")

    # Kubernetes, rendered.
    known = serve_flags if serve_flags is not None else set()
    base = render(os.path.join(ROOT, "docker/k8s/base"))
    tmp = tempfile.mkdtemp()
    try:
        shutil.copytree(os.path.join(ROOT, "docker/k8s"), os.path.join(tmp, "k8s"))
        os.makedirs(os.path.join(tmp, "k8s/tls/secrets"), exist_ok=True)
        for f in ("tls.crt", "tls.key", "tokens"):
            open(os.path.join(tmp, "k8s/tls/secrets", f), "w").close()
        tls = render(os.path.join(tmp, "k8s/tls"))
    finally:
        shutil.rmtree(tmp)
    if base is None:  # no kubectl: the base files as they are
        base = [o for f, ds in docs.items() if "/k8s/base/" in f for o in ds
                if o.get("kind") != "Kustomization"]
    if serve_flags is None:
        known = set(flag_values(
            [a for o in base if o["kind"] == "Deployment"
             for a in o["spec"]["template"]["spec"]["containers"][0]["args"]]))
    check_objects(base, "k8s/base", known, server_metrics)
    if tls is not None:
        check_objects(tls, "k8s/tls", known | {"tls-cert", "tls-key", "auth-token-file"}
                      if serve_flags is None else known, server_metrics)

    # The Deployment's args on the real binary.
    if serve_flags is not None:
        d = next(o for o in base if o["kind"] == "Deployment")
        args = [a for a in d["spec"]["template"]["spec"]["containers"][0]["args"]
                if not a.startswith("--metrics=")]
        p = subprocess.Popen([mlclust, "serve", "--listen", "127.0.0.1:0", "--drain-seconds",
                              "25", "--metrics=127.0.0.1:0"] + args,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        # Up as soon as it says it serves (no fixed wait), then drained by SIGTERM.
        started = []
        killer = threading.Timer(60, p.kill)  # a server that never says it serves
        killer.start()
        for line in p.stdout:
            started.append(line)
            if "serving mlclust.v1.Clustering" in line:
                break
        killer.cancel()
        p.send_signal(signal.SIGTERM)
        out = "".join(started) + p.communicate(timeout=30)[0]
        check(p.returncode == 0 and "queue capacity 32; CPU workers 2" in out,
              "mlclust serve starts with the Deployment's args and exits 0 on SIGTERM")

    print("\ncheck-deploy: %s" % ("all checks passed" if not errors else
                                  "%d FAILED" % len(errors)))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
