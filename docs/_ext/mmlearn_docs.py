"""Sphinx extension of the mmlearn documentation.

Two directives:

``.. pydrake_system::`` (the block every LeafSystem docstring carries, in Drake's own format)
    renders the system's ports as a block diagram: inputs on the left, outputs on the right,
    and below it the class's accessor of each port (``get_<port>_input_port()``,
    ``get_<port>_output_port()``) when it has one. The content is YAML with ``name``,
    ``input_ports`` and ``output_ports``.

``.. screenshot:: NAME`` (in MyST: ````{screenshot} NAME````)
    shows ``docs/images/NAME.png`` when it exists; otherwise a line saying which recording it
    shows, so that a checkout without the generated pictures still builds without warnings.
    The optional content is the caption.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from docutils import nodes
from docutils.parsers.rst import Directive, directives

IMAGES = Path(__file__).resolve().parents[1] / "images"


def port_diagram(name: str, inputs: list[str], outputs: list[str]) -> str:
    """The ports of system ``name`` as a text block diagram (Drake's style)."""
    rows = max(len(inputs), len(outputs), 1)
    left = max([len(p) for p in inputs] + [0])
    inner = len(name) + 4
    lines = [" " * (left + 4) + "+" + "-" * inner + "+"]
    for i in range(rows):
        label = name if i == (rows - 1) // 2 else ""
        port_in = inputs[i] if i < len(inputs) else ""
        arrow_in = " -> " if port_in else "    "
        port_out = outputs[i] if i < len(outputs) else ""
        arrow_out = " -> " + port_out if port_out else ""
        lines.append(f"{port_in:>{left}}{arrow_in}|{label:^{inner}}|{arrow_out}")
    lines.append(" " * (left + 4) + "+" + "-" * inner + "+")
    return "\n".join(line.rstrip() for line in lines)


def port_getters(cls, inputs: list[str], outputs: list[str]) -> tuple[list[str], list[str]]:
    """The accessors of ``cls`` for its ports, in port order, and the ports without one.

    An accessor is ``get_<port>_input_port`` / ``get_<port>_output_port``; a frame suffix
    (``force_W`` -> ``get_force_input_port``) and an index (``color_image_0`` ->
    ``get_color_image_input_port``, which takes the index) are dropped when the exact name has
    none; ``name (optional)`` is ``name``; ``...`` lines are skipped. Ports without an
    accessor are returned as ``GetInputPort("name")`` / ``GetOutputPort("name")``."""
    import re

    getters, missing = [], []
    for ports, kind, by_name in ((inputs, "input", "GetInputPort"),
                                 (outputs, "output", "GetOutputPort")):
        for port in ports:
            base = str(port).split()[0] if str(port).split() else ""
            if not base or base.startswith("..."):
                continue
            for cand in (base, re.sub(r"_W$", "", base), re.sub(r"_(\d+|\{.*\})$", "", base)):
                name = f"get_{cand}_{kind}_port"
                if cls is not None and callable(getattr(cls, name, None)):
                    if name not in getters:
                        getters.append(name)
                    break
            else:
                missing.append(f'{by_name}("{base}")')
    return getters, missing


def _system_class(name: str, module: str | None):
    """The class ``name`` from ``module`` (the page's current module) or ``mmlearn.systems``."""
    import importlib

    for mod in (module, "mmlearn.systems"):
        if not mod:
            continue
        try:
            obj = getattr(importlib.import_module(mod), name, None)
        except ImportError:
            obj = None
        if isinstance(obj, type):
            return obj
    return None


class PydrakeSystem(Directive):
    """``.. pydrake_system::`` -> a literal block diagram of the ports."""

    has_content = True

    def run(self):
        text = "\n".join(self.content)
        try:
            spec = yaml.safe_load(text) or {}
        except yaml.YAMLError as exc:
            raise self.error(f"pydrake_system: not YAML: {exc}") from exc
        if not isinstance(spec, dict) or "name" not in spec:
            raise self.error("pydrake_system: needs a 'name'")
        inputs = [str(p) for p in spec.get("input_ports") or []]
        outputs = [str(p) for p in spec.get("output_ports") or []]
        diagram = port_diagram(str(spec["name"]), inputs, outputs)
        block = nodes.literal_block(diagram, diagram)
        block["language"] = "text"
        block["classes"].append("pydrake-system")
        title = nodes.paragraph()
        title += nodes.strong(text="Ports")
        env = getattr(self.state.document.settings, "env", None)
        module = env.ref_context.get("py:module") if env is not None else None
        getters, missing = port_getters(_system_class(str(spec["name"]), module), inputs, outputs)
        if not getters:
            return [title, block]
        para = nodes.paragraph()
        para += nodes.Text("Port accessors: ")
        for i, g in enumerate(getters):
            if i:
                para += nodes.Text(", ")
            para += nodes.literal(text=f"{g}()")
        if missing:
            para += nodes.Text("; by name: ")
            for i, g in enumerate(missing):
                if i:
                    para += nodes.Text(", ")
                para += nodes.literal(text=g)
        para += nodes.Text(".")
        return [title, block, para]


class Screenshot(Directive):
    """``.. screenshot:: NAME`` -> docs/images/NAME.png if it exists, else a note."""

    required_arguments = 1
    has_content = True
    option_spec = {"width": directives.unchanged}

    def run(self):
        name = self.arguments[0]
        caption = " ".join(self.content).strip()
        path = IMAGES / f"{name}.png"
        if not path.exists():
            note = nodes.paragraph()
            note += nodes.emphasis(
                text=f"Screenshot {name}.png: {caption or name} "
                     "(generated into docs/images/; not present in this build).")
            return [note]
        env = self.state.document.settings.env
        rel = Path("/") / path.relative_to(Path(env.srcdir))
        image = nodes.image(uri=str(rel), alt=caption or name)
        image["width"] = self.options.get("width", "100%")
        figure = nodes.figure("", image)
        if caption:
            figure += nodes.caption(caption, caption)
        return [figure]


def setup(app):
    app.add_directive("pydrake_system", PydrakeSystem)
    app.add_directive("screenshot", Screenshot)
    return {"version": "1.0", "parallel_read_safe": True, "parallel_write_safe": True}
