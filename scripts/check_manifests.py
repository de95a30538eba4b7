"""Validates deploy/k8s and deploy/knative offline (run by scripts/check-deploy.sh).

Every Kubernetes resource is checked strictly (no unknown field) against the schemas that
kubernetes-validate bundles; a kind without a schema is an error, not a warning. The Knative
Service has no bundled schema, so its pod template is checked as a Pod, and its own fields
by hand. Then the facts the files share: the kustomization lists every manifest, selectors
match the pod labels, probes hit /readyz and /healthz, and the grace period outlasts the
preStop pause plus the proxy's own shutdown grace.
"""

import sys
from pathlib import Path

import kubernetes_validate
import yaml

K8S_VERSION = "1.37.0"
ROOT = Path(__file__).resolve().parent.parent
K8S = ROOT / "deploy" / "k8s"
KNATIVE = ROOT / "deploy" / "knative" / "service.yaml"
# The proxy's default of PENMESH_SHUTDOWN_GRACE_SECS (proxy/src/config.rs).
DEFAULT_SHUTDOWN_GRACE_SECS = 10

errors = []


def fail(where, message):
    errors.append(f"{where}: {message}")


def load(path):
    try:
        docs = [d for d in yaml.safe_load_all(path.read_text()) if d is not None]
    except (OSError, yaml.YAMLError) as e:
        fail(path.relative_to(ROOT), f"cannot read: {e}")
        return []
    return docs


def validate(where, resource):
    try:
        kubernetes_validate.validate(resource, K8S_VERSION, strict=True)
    except kubernetes_validate.ValidationError as e:
        path = ".".join(str(p) for p in e.path)
        fail(where, f"{path}: {e.message}")
    except kubernetes_validate.SchemaNotFoundError as e:
        fail(where, f"no schema for {e}")
    except kubernetes_validate.InvalidSchemaError as e:
        fail(where, f"invalid schema: {e}")


def env_of(container):
    return {e["name"]: e for e in container.get("env", [])}


def check_container(where, container, probes_need_port):
    for probe, path in (("readinessProbe", "/readyz"), ("livenessProbe", "/healthz")):
        got = container.get(probe, {}).get("httpGet", {}).get("path")
        if got != path:
            fail(where, f"{probe} must GET {path}, not {got}")
        if probes_need_port and "port" not in container.get(probe, {}).get("httpGet", {}):
            fail(where, f"{probe} names no port")
    url = env_of(container).get("PENMESH_DATABASE_URL", {})
    if url.get("valueFrom", {}).get("secretKeyRef", {}).get("name") != "penmesh-database":
        fail(where, "PENMESH_DATABASE_URL must come from the Secret penmesh-database")
    context = container.get("securityContext", {})
    if context.get("readOnlyRootFilesystem") is not True:
        fail(where, "the root file system must be read-only")
    resources = container.get("resources", {})
    for kind in ("requests", "limits"):
        for what in ("cpu", "memory"):
            if what not in resources.get(kind, {}):
                fail(where, f"resources.{kind}.{what} missing")


def shutdown_grace(container):
    value = env_of(container).get("PENMESH_SHUTDOWN_GRACE_SECS", {}).get("value")
    return int(value) if value is not None else DEFAULT_SHUTDOWN_GRACE_SECS


def check_k8s():
    kustomization = yaml.safe_load((K8S / "kustomization.yaml").read_text())
    listed = kustomization.get("resources", [])
    present = sorted(
        p.name
        for p in K8S.glob("*.yaml")
        if p.name not in ("kustomization.yaml", "secret.example.yaml")
    )
    if sorted(listed) != present:
        fail("deploy/k8s/kustomization.yaml", f"resources {sorted(listed)} != files {present}")
    by_kind = {}
    for name in present + ["secret.example.yaml"]:
        path = K8S / name
        for resource in load(path):
            where = f"deploy/k8s/{name} ({resource.get('kind')})"
            validate(where, resource)
            by_kind.setdefault(resource.get("kind"), []).append((where, resource))

    deployments = by_kind.get("Deployment", [])
    if len(deployments) != 1:
        fail("deploy/k8s", f"expected one Deployment, found {len(deployments)}")
        return
    where, deployment = deployments[0]
    spec = deployment["spec"]
    pod = spec["template"]["spec"]
    labels = spec["template"]["metadata"].get("labels", {})
    if spec.get("replicas", 1) < 2:
        fail(where, "fewer than two replicas")
    if pod.get("securityContext", {}).get("runAsNonRoot") is not True:
        fail(where, "runAsNonRoot is not set")
    container = pod["containers"][0]
    check_container(where, container, probes_need_port=True)
    pause = container.get("lifecycle", {}).get("preStop", {}).get("sleep", {}).get("seconds", 0)
    if pause <= 0:
        fail(where, "no preStop pause")
    grace = pod.get("terminationGracePeriodSeconds", 30)
    if grace <= pause + shutdown_grace(container):
        fail(where, f"terminationGracePeriodSeconds {grace} <= preStop {pause} + shutdown grace")
    images = {i["name"] for i in kustomization.get("images", [])}
    if container["image"].split(":")[0] not in images:
        fail(where, f"image {container['image']} is not set by the kustomization")

    for kind in ("Service", "PodDisruptionBudget"):
        for where, resource in by_kind.get(kind, []) or [(f"deploy/k8s ({kind})", None)]:
            if resource is None:
                fail(where, "missing")
                continue
            selector = resource["spec"]["selector"]
            selector = selector.get("matchLabels", selector) if kind != "Service" else selector
            if any(labels.get(k) != v for k, v in selector.items()):
                fail(where, f"selector {selector} does not match the pod labels {labels}")
    for where, ingress in by_kind.get("Ingress", []):
        for rule in ingress["spec"].get("rules", []):
            for path in rule.get("http", {}).get("paths", []):
                service = path["backend"]["service"]["name"]
                if service not in {r["metadata"]["name"] for _, r in by_kind.get("Service", [])}:
                    fail(where, f"backend {service} is no Service here")


def check_knative():
    where = "deploy/knative/service.yaml"
    docs = load(KNATIVE)
    if len(docs) != 1:
        fail(where, f"expected one document, found {len(docs)}")
        return
    service = docs[0]
    if (service.get("apiVersion"), service.get("kind")) != ("serving.knative.dev/v1", "Service"):
        fail(where, "not a serving.knative.dev/v1 Service")
        return
    template = service["spec"]["template"]
    annotations = template.get("metadata", {}).get("annotations", {})
    for key, value in annotations.items():
        if not isinstance(value, str):
            fail(where, f"annotation {key} must be a string, not {value!r}")
    for key in ("min-scale", "max-scale", "target"):
        value = annotations.get(f"autoscaling.knative.dev/{key}")
        if value is None or not str(value).isdigit():
            fail(where, f"autoscaling.knative.dev/{key} must be a whole number, not {value!r}")
    spec = dict(template["spec"])
    # Knative's own fields, then the rest is a pod spec.
    concurrency = spec.pop("containerConcurrency", 0)
    timeout = spec.pop("timeoutSeconds", 300)
    if not isinstance(concurrency, int) or not 0 <= concurrency <= 1000:
        fail(where, f"containerConcurrency {concurrency!r} is not 0..1000")
    if not isinstance(timeout, int) or timeout < 600:
        fail(where, f"timeoutSeconds {timeout!r}: a drawing WebSocket needs at least 600 s")
    target = int(annotations.get("autoscaling.knative.dev/target", "0") or 0)
    if concurrency and target > concurrency:
        fail(where, f"target {target} above containerConcurrency {concurrency}")
    # Knative names the container and fills in the probes' port; do the same for the check.
    spec = yaml.safe_load(yaml.safe_dump(spec))
    for container in spec.get("containers", []):
        container.setdefault("name", "user-container")
        port = (container.get("ports") or [{}])[0].get("containerPort", 8080)
        for probe in ("readinessProbe", "livenessProbe"):
            container.get(probe, {}).get("httpGet", {}).setdefault("port", port)
    pod = {"apiVersion": "v1", "kind": "Pod", "metadata": {"name": "knative"}, "spec": spec}
    validate(f"{where} (pod template)", pod)
    containers = spec.get("containers", [])
    if len(containers) != 1:
        fail(where, "expected one container")
        return
    container = containers[0]
    check_container(where, container, probes_need_port=False)
    if [p.get("name") for p in container.get("ports", [])] != ["http1"]:
        fail(where, "the port must be named http1 (WebSocket needs HTTP/1.1)")
    if "PORT" in env_of(container):
        fail(where, "Knative sets PORT itself")


def main():
    check_k8s()
    check_knative()
    for error in errors:
        print(f"error: {error}", file=sys.stderr)
    if errors:
        return 1
    print(f"manifests: deploy/k8s and deploy/knative valid against Kubernetes {K8S_VERSION}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
