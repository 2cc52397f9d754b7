#!/usr/bin/python3
"""Prints the comment block of JobSpec.options in proto/mlclust/v1/mlclust.proto: every
option key of every algorithm with its type, range and default, from the registry as
`mlclust info --json` reports it (GetServerInfo). The registry is the one list; this block
is its copy for readers of the proto, checked by tests/client/wiring_cli_test.sh.

    /usr/bin/python3 scripts/proto_options_doc.py build/client/mlclust            # print it
    /usr/bin/python3 scripts/proto_options_doc.py build/client/mlclust --write \
        proto/mlclust/v1/mlclust.proto                                          # replace it
"""
import json
import subprocess
import sys
import textwrap


def value_text(option):
    if option["type"] == "choice":
        return "|".join(option["choices"])
    low, high = option["low"], option["high"]
    fmt = (lambda v: str(int(v))) if option["type"] == "integer" else (lambda v: f"{v:.7g}")
    return f"{option['type']} in [{fmt(low)}, {fmt(high)}]"


def main():
    info = json.loads(subprocess.run([sys.argv[1], "info", "--json"], check=True,
                                     capture_output=True, text=True).stdout)
    lines = ["  // BEGIN options (scripts/proto_options_doc.py from the registry; help texts: "
             "GetServerInfo)"]
    mesh_energy_options = None
    for algorithm in info["algorithms"]:
        kind = "mesh" if algorithm["input_kind"] == "INPUT_KIND_DRACO_MESH" else "points"
        options = algorithm["options"]
        if kind == "mesh":
            # The energy options close every mesh algorithm's list: print them once.
            names = [o["name"] for o in options]
            start = names.index("density") if "density" in names else len(names)
            mesh_energy_options = options[start:]
            options = options[:start]
        items = [f"{o['name']} ({value_text(o)}; default {o['default_value']})" for o in options]
        text = f"{kind} {algorithm['name']}: " + ("; ".join(items) if items else "none of its own")
        lines += ["  //   " + l for l in textwrap.wrap(text, 88 - 7, subsequent_indent="  ", break_on_hyphens=False)]
    if mesh_energy_options:
        items = [f"{o['name']} ({value_text(o)}; default {o['default_value']})"
                 for o in mesh_energy_options]
        text = "every mesh algorithm, energy options: " + "; ".join(items)
        lines += ["  //   " + l for l in textwrap.wrap(text, 88 - 7, subsequent_indent="  ", break_on_hyphens=False)]
    lines.append("  // END options")
    block = "\n".join(lines) + "\n"
    if len(sys.argv) == 4 and sys.argv[2] == "--write":
        with open(sys.argv[3]) as f:
            text = f.read()
        begin = text.index("  // BEGIN options")
        end = text.index("  // END options\n", begin) + len("  // END options\n")
        with open(sys.argv[3], "w") as f:
            f.write(text[:begin] + block + text[end:])
    else:
        sys.stdout.write(block)


main()
