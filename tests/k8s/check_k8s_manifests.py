#!/usr/bin/env python3
"""Checks the Kubernetes manifests of the watergs batch (scripts/k8s/*.yaml) without a cluster: YAML
syntax, the fields a batch/v1 Job needs and the rules the API server enforces for an Indexed Job with a
pod failure policy, and that the commands they run exist in this repository with the options they pass
(run_scene.sh's, watergs_batch.sh's, batch_tool.py's) and the exit code the failure policy expects.
Needs python3-yaml (Debian's /usr/bin/python3 has it after scripts/install_deps.sh); exits 77 (CTest
skip) when no interpreter here has it."""
import os
import re
import sys

try:
    import yaml
except ImportError:
    # A virtualenv's python3 without PyYAML: Debian's own interpreter has the package.
    if os.path.exists("/usr/bin/python3") and os.path.realpath(sys.executable) != os.path.realpath(
            "/usr/bin/python3") and not os.environ.get("WATERGS_K8S_CHECK_REEXEC"):
        os.environ["WATERGS_K8S_CHECK_REEXEC"] = "1"
        os.execv("/usr/bin/python3", ["/usr/bin/python3"] + sys.argv)
    print("SKIP: no python3 with PyYAML here (Debian package python3-yaml: bash scripts/install_deps.sh --tests)")
    sys.exit(77)

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
IMAGE_ROOT = "/opt/watergs"  # where scripts/k8s/Dockerfile puts the checkout
DNS_LABEL = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")
QUANTITY = re.compile(r"^[0-9]+(\.[0-9]+)?(m|k|M|G|T|Ki|Mi|Gi|Ti)?$")
POD_FAILURE_ACTIONS = {"FailJob", "FailIndex", "Ignore", "Count"}

errors = []


def error(where, problem):
    errors.append(f"{where}: {problem}")


def need(obj, key, kind, where):
    value = obj.get(key) if isinstance(obj, dict) else None
    if not isinstance(value, kind):
        error(where, f"'{key}' missing or not a {kind.__name__}")
        return kind()
    return value


def read(path):
    with open(path) as f:
        return f.read()


CASE_LABEL = re.compile(r"^[ \t]+((?:-[-a-z_]+[ \t]*\|[ \t]*(?:\\\n[ \t]*)?)*-[-a-z_]+)\)", re.M)


def script_options(path):
    """The --options a script accepts: its case labels (shell, with the files it sources from this
    repository) or its add_argument calls (Python)."""
    text = read(path)
    options = set(re.findall(r"add_argument\(\"(--[a-z_]+)\"", text))
    for label in CASE_LABEL.findall(text):
        options |= set(re.findall(r"--[a-z_]+", label))
    for sourced in re.findall(r"^source \"[^\"]*/([a-z_]+\.sh)\"", text, re.M):
        for root, _, files in os.walk(os.path.join(REPO, "scripts")):
            if sourced in files:
                options |= script_options(os.path.join(root, sourced))
    return options


def check_command(container, where):
    """The command runs a script of this repository, with options that script takes."""
    words = [str(w) for w in container.get("command", []) + container.get("args", [])]
    scripts = [w for w in words if w.startswith(IMAGE_ROOT + "/")]
    if not scripts:
        error(where, f"runs no script under {IMAGE_ROOT} (the image's checkout)")
        return
    local = os.path.join(REPO, os.path.relpath(scripts[0], IMAGE_ROOT))
    if not os.path.isfile(local):
        error(where, f"{scripts[0]}: no such file in the repository ({local})")
        return
    accepted = script_options(local)
    for word in words:
        if word.startswith("--") and word not in accepted:
            error(where, f"{os.path.basename(local)} has no option {word}")


def check_container(c, volumes, where):
    name = need(c, "name", str, where)
    where = f"{where} '{name}'"
    if not DNS_LABEL.match(name):
        error(where, "container name is not a DNS label")
    need(c, "image", str, where)
    if not isinstance(c.get("command"), list) or not all(isinstance(w, str) for w in c["command"]):
        error(where, "command must be a list of strings")
    if not isinstance(c.get("args", []), list) or not all(isinstance(w, str) for w in c.get("args", [])):
        error(where, "args must be a list of strings (quote numbers)")
    resources = need(c, "resources", dict, where)
    for part in ("requests", "limits"):
        for res, qty in need(resources, part, dict, where).items():
            if res not in ("cpu", "memory") or not isinstance(qty, str) or not QUANTITY.match(qty):
                error(where, f"resources.{part}.{res} '{qty}' is not a quoted quantity of cpu or memory")
    for mount in c.get("volumeMounts", []):
        if mount.get("name") not in volumes:
            error(where, f"volumeMount '{mount.get('name')}' names no volume of the pod")
        if not str(mount.get("mountPath", "")).startswith("/"):
            error(where, "volumeMount without an absolute mountPath")
    check_command(c, where)
    return name


def check_job(doc, where):
    if doc.get("apiVersion") != "batch/v1" or doc.get("kind") != "Job":
        error(where, f"not a batch/v1 Job ({doc.get('apiVersion')} {doc.get('kind')})")
        return None
    name = need(need(doc, "metadata", dict, where), "name", str, where)
    if not DNS_LABEL.match(name) or len(name) > 63:
        error(where, f"metadata.name '{name}' is not a DNS label of at most 63 characters")
    where = f"{where} Job {name}"
    spec = need(doc, "spec", dict, where)
    pod = need(need(spec, "template", dict, where), "spec", dict, where)
    restart = pod.get("restartPolicy")
    if restart not in ("Never", "OnFailure"):
        error(where, f"template.spec.restartPolicy '{restart}' (a Job needs Never or OnFailure)")
    volumes = {v.get("name") for v in pod.get("volumes", [])}
    containers = [check_container(c, volumes, f"{where} container")
                  for c in need(pod, "containers", list, where)]
    for c in pod.get("initContainers", []):
        check_container(c, volumes, f"{where} initContainer")
    if not containers:
        error(where, "no container")
    if spec.get("completionMode") == "Indexed":
        for key in ("completions", "parallelism"):
            if not isinstance(spec.get(key), int) or spec[key] < 1:
                error(where, f"an Indexed Job needs spec.{key} >= 1")
    policy = spec.get("podFailurePolicy")
    if policy is not None:
        if restart != "Never":
            error(where, "podFailurePolicy needs restartPolicy Never")
        for rule in need(policy, "rules", list, where):
            action = rule.get("action")
            if action not in POD_FAILURE_ACTIONS:
                error(where, f"podFailurePolicy action '{action}'")
            if action == "FailIndex" and "backoffLimitPerIndex" not in spec:
                error(where, "podFailurePolicy FailIndex needs spec.backoffLimitPerIndex")
            if ("onExitCodes" in rule) == ("onPodConditions" in rule):
                error(where, "a podFailurePolicy rule needs exactly one of onExitCodes, onPodConditions")
            codes = rule.get("onExitCodes")
            if codes:
                if codes.get("containerName") not in containers:
                    error(where, f"onExitCodes.containerName '{codes.get('containerName')}' is no container")
                if codes.get("operator") not in ("In", "NotIn"):
                    error(where, f"onExitCodes.operator '{codes.get('operator')}'")
                values = codes.get("values")
                if not isinstance(values, list) or not values or not all(isinstance(v, int) for v in values):
                    error(where, "onExitCodes.values must be a list of integers")
                elif codes.get("operator") == "In" and 0 in values:
                    error(where, "onExitCodes In must not list 0")
    if "backoffLimitPerIndex" in spec and spec.get("completionMode") != "Indexed":
        error(where, "backoffLimitPerIndex needs completionMode Indexed")
    return spec


def main():
    folder = os.path.join(REPO, "scripts", "k8s")
    manifests = sorted(f for f in os.listdir(folder) if f.endswith(".yaml"))
    if not manifests:
        sys.exit(f"FAIL: no manifest in {folder}")
    indexed = 0
    for file in manifests:
        path = os.path.join(folder, file)
        try:
            docs = [d for d in yaml.safe_load_all(read(path)) if d is not None]
        except yaml.YAMLError as e:
            error(file, f"YAML syntax: {e}")
            continue
        for k, doc in enumerate(docs):
            spec = check_job(doc, f"{file} document {k + 1}") if isinstance(doc, dict) else None
            if spec is None:
                continue
            if spec.get("completionMode") == "Indexed":
                indexed += 1
                # The exit code the failure policy fails an index on is run_scene.sh's for a failed scene.
                run_scene = read(os.path.join(REPO, "scripts", "slurm", "run_scene.sh"))
                failed = re.search(r"EXIT_FAILED=(\d+)", run_scene)
                codes = [r["onExitCodes"]["values"] for r in spec.get("podFailurePolicy", {}).get("rules", [])
                         if r.get("action") == "FailIndex" and "onExitCodes" in r]
                if not failed or [int(failed.group(1))] not in codes:
                    error(file, f"FailIndex exit codes {codes} are not run_scene.sh's EXIT_FAILED "
                                f"({failed.group(1) if failed else 'not found'})")
    if indexed == 0:
        error("scripts/k8s", "no Indexed Job")
    dockerfile = read(os.path.join(folder, "Dockerfile"))
    if f"COPY . {IMAGE_ROOT}" not in dockerfile or "scripts/install_deps.sh" not in dockerfile:
        error("Dockerfile", f"does not copy the checkout to {IMAGE_ROOT} and run scripts/install_deps.sh")
    if errors:
        print("\n".join("FAIL: " + e for e in errors))
        sys.exit(1)
    print(f"OK: {len(manifests)} manifests ({indexed} Indexed Job), Dockerfile")


if __name__ == "__main__":
    main()
