"""A mobile manipulator in MuJoCo, read from its URDF, with what the URDF lacks.

A URDF describes links, joints and their limits; it has no drives, no floor and no servo
loops. This module builds them (the table in actuators.toml says with which numbers):

- a **differential-drive base** (platform `unicycle`): the URDF's root link on a free joint,
  on a floor, carried by its two drive wheels (velocity servos, torque limited to the URDF's
  effort) and frictionless casters; the command (v, ω) becomes the wheel rates
  `(v ∓ ω b/2) / R` from the wheel radius R and track b read from the URDF;
- an **omnidirectional base** (platform `omni`) for an arm-only URDF: a planar body on slide,
  slide and hinge joints, driven in its own frame by velocity servos with force limits, the
  arm's root link mounted on it;
- **arm and torso servos** on the chain from the base link to the tip link: velocity servos
  with the URDF's effort limits and gravity compensation; joints off the chain held still.

What the plant measures comes from here too: the base pose from the simulator (as a
motion-capture system sees it) or from wheel odometry, the joints from the joint positions,
and — for the plant's own figures, never sent — the effector's pose, wheel slip and the
drives' saturation.
"""

import math
import os
import sysconfig
import tomllib
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_TABLE = os.path.join(HERE, "actuators.toml")
MOVABLE = ("revolute", "continuous", "prismatic")
# The friction feedforward's direction is tanh(u / 0.01 rad/s): all of the URDF's friction
# from a commanded 0.03 rad/s (or m/s), none at rest (no chatter about zero).
FRICTION_RATE = 100.0


class ModelError(Exception):
    """A robot the MuJoCo plant cannot build (a bad file, link or table entry), named."""


def one_line(e):
    """MuJoCo's message as one line ("Error: …\nElement name …, line 3" → "…; element …")."""
    text = " ".join(str(e).split())
    return text[:400] + ("…" if len(text) > 400 else "")


def robots_dir():
    """example-robot-data's robots folder (PyPI `example-robot-data`, installed by
    scripts/setup into target/py), or $COMPANION_ROBOTS."""
    if os.environ.get("COMPANION_ROBOTS"):
        return os.environ["COMPANION_ROBOTS"]
    return os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix", "share", "example-robot-data", "robots")


def resolve_robot_file(path):
    """`path` as given, or relative to example-robot-data's robots folder."""
    if os.path.exists(path):
        return path
    alt = os.path.join(robots_dir(), path)
    if os.path.exists(alt):
        return alt
    raise ModelError(f"robot file {path}: not found (nor under {robots_dir()})")


# ----- the table --------------------------------------------------------------------------


def merge(base, over, where=""):
    """`over`'s keys into a copy of `base`; a key `base` does not have is an error (typos
    must not be silently ignored), except under `joint`."""
    out = dict(base)
    for k, v in over.items():
        here = f"{where}.{k}" if where else k
        if k not in base and where != "joint" and k != "joint":
            keys = ", ".join(sorted(base)) if where else ", ".join(sorted(x for x in base if x != "joint"))
            within = f"{where} has" if where else "the sections are"
            raise ModelError(
                f"actuator table: unknown key {here} ({within} {keys}; one joint's own: joint.NAME.kv, .effort, "
                f".speed, .armature)"
            )
        if isinstance(v, dict) and isinstance(base.get(k), dict):
            out[k] = merge(base[k], v, here)
        else:
            out[k] = v
    return out


def load_table(files=(), sets=()):
    """The default table, each file of `files` over it, then each `section.key=value` of
    `sets` (the value in TOML syntax)."""
    with open(DEFAULT_TABLE, "rb") as f:
        table = tomllib.load(f)
    table.setdefault("joint", {})
    for path in files:
        try:
            with open(path, "rb") as f:
                table = merge(table, tomllib.load(f))
        except (OSError, tomllib.TOMLDecodeError) as e:
            raise ModelError(f"actuator table {path}: {e}")
    for item in sets:
        key, eq, value = item.partition("=")
        if not eq or "." not in key:
            raise ModelError(f"--set {item!r}: SECTION.KEY=VALUE, e.g. arm.time_constant=0.002 or joint.arm_1_joint.kv=200")
        *sections, last = key.strip().split(".")
        try:
            parsed = tomllib.loads(f"x = {value.strip()}")["x"]
        except tomllib.TOMLDecodeError as e:
            raise ModelError(f"--set {item!r}: the value is not TOML ({e})")
        nested = {last: parsed}
        for s in reversed(sections):
            nested = {s: nested}
        table = merge(table, nested)
    return table


# ----- the URDF ---------------------------------------------------------------------------


def rpy_matrix(r, p, y):
    """R_z(y) R_y(p) R_x(r), as URDF's rpy, as a numpy 3×3."""
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def numbers(text, n, what):
    if text is None:
        return [0.0] * n
    try:
        v = [float(x) for x in text.split()[: n + 1]]
    except ValueError:
        v = []
    if len(v) != n or not all(math.isfinite(x) for x in v):
        raise ModelError(f"{what}: {n} finite numbers expected, got {text[:80]!r}")
    return v


class Urdf:
    """The parts of a URDF the plant needs: its tree of joints, their limits, the collision
    geometries of each link."""

    def __init__(self, path):
        self.path = resolve_robot_file(path)
        try:
            self.root = ET.parse(self.path).getroot()
        except (OSError, ET.ParseError) as e:
            raise ModelError(f"URDF {path}: {e}")
        if self.root.tag != "robot":
            raise ModelError(f"URDF {path}: the root element is <{self.root.tag}>, not <robot>")
        self.links = {l.get("name"): l for l in self.root.findall("link")}
        self.joints = {}
        self.parent_joint = {}
        for j in self.root.findall("joint"):
            name, kind = j.get("name"), j.get("type")
            what = f"URDF {path}: joint {str(name)[:80]!r}"
            parent, child = j.find("parent"), j.find("child")
            if parent is None or child is None or parent.get("link") is None or child.get("link") is None:
                raise ModelError(f"{what} has no <parent link> or <child link>")
            parent, child = parent.get("link"), child.get("link")
            o = j.find("origin")
            xyz = numbers(o.get("xyz") if o is not None else None, 3, f"{what}: origin xyz")
            rpy = numbers(o.get("rpy") if o is not None else None, 3, f"{what}: origin rpy")
            a = j.find("axis")
            axis = numbers(a.get("xyz") if a is not None else "1 0 0", 3, f"{what}: axis")
            lim = j.find("limit")

            def get(k, d, lim=lim, what=what):
                text = lim.get(k, d) if lim is not None else d
                try:
                    return float(text)
                except ValueError:
                    raise ModelError(f"{what}: <limit {k}>={str(text)[:80]!r} is not a number")

            self.joints[name] = {
                "name": name,
                "type": kind,
                "parent": parent,
                "child": child,
                "xyz": xyz,
                "rpy": rpy,
                "axis": axis,
                "lower": get("lower", "nan"),
                "upper": get("upper", "nan"),
                "effort": get("effort", "nan"),
                "velocity": get("velocity", "nan"),
            }
            self.parent_joint[child] = name
        children = set(self.parent_joint)
        roots = [l for l in self.links if l not in children]
        self.root_link = roots[0] if len(roots) == 1 else None
        # What the plant changed of the file for MuJoCo (mujoco_xml), by link.
        self.fixes = []
        self.mesh_fixes = []

    def path_joints(self, base, tip):
        """The joints from link `base` down to link `tip` (base first)."""
        for link in (base, tip):
            if link not in self.links:
                raise ModelError(f"URDF {self.path}: no link named {link!r}")
        out, link = [], tip
        while link != base:
            # At most one step per joint: a loop in the file ends the walk, refused.
            if link not in self.parent_joint or len(out) > len(self.joints):
                raise ModelError(f"URDF {self.path}: link {tip!r} is not below link {base!r}")
            j = self.joints[self.parent_joint[link]]
            out.append(j)
            link = j["parent"]
        return out[::-1]

    def chain(self, base, tip):
        """The movable joints from `base` to `tip`, base first."""
        return [j for j in self.path_joints(base, tip) if j["type"] in MOVABLE]

    def mujoco_xml(self, keep_visuals=True):
        """The URDF as MuJoCo loads it: mesh file names made absolute (`package://PKG/…`
        found in an ancestor folder named PKG), meshes MuJoCo cannot read (.dae) dropped —
        a collision mesh becomes the visual where the visual is one — collision meshes
        dropped (the plant's contacts are the primitives: wheels, casters), inertias that
        are not positive definite made diagonal (MuJoCo refuses them: the TIAGo's antennas),
        and a compiler element."""
        root = ET.fromstring(ET.tostring(self.root))
        self.fixes, self.mesh_fixes = [], []
        for link in root.findall("link"):
            name = link.get("name")
            stl_collision = None
            for c in list(link.findall("collision")):
                mesh = c.find("geometry/mesh")
                if mesh is not None:
                    f = self._mesh_file(mesh.get("filename"))
                    if f and f.lower().endswith(".stl") and stl_collision is None:
                        stl_collision = (c, f)
                    link.remove(c)
            for v in list(link.findall("visual")):
                mesh = v.find("geometry/mesh")
                if mesh is None:
                    if not keep_visuals:
                        link.remove(v)
                    continue
                given = str(mesh.get("filename"))
                f = self._mesh_file(mesh.get("filename"))
                if not keep_visuals:
                    link.remove(v)
                elif f is None:
                    link.remove(v)
                    self.mesh_fixes.append({"link": name, "fix": f"visual mesh {given[:120]} not found: dropped"})
                elif f.lower().endswith(".stl"):
                    mesh.set("filename", f)
                elif stl_collision is not None:
                    mesh.set("filename", stl_collision[1])
                    src = stl_collision[0].find("geometry/mesh")
                    if src.get("scale"):
                        mesh.set("scale", src.get("scale"))
                    else:
                        mesh.attrib.pop("scale", None)
                    o = stl_collision[0].find("origin")
                    vo = v.find("origin")
                    if vo is not None:
                        v.remove(vo)
                    if o is not None:
                        v.insert(0, o)
                    self.mesh_fixes.append({"link": name, "fix": f"visual mesh {os.path.basename(f)} (MuJoCo reads no "
                                            f"{os.path.splitext(f)[1]}) replaced by its collision mesh "
                                            f"{os.path.basename(stl_collision[1])}"})
                else:
                    link.remove(v)
                    self.mesh_fixes.append({"link": name, "fix": f"visual mesh {os.path.basename(f)} (MuJoCo reads no "
                                            f"{os.path.splitext(f)[1]}, and the link has no .stl collision mesh): dropped"})
            # MuJoCo loads a NaN or an infinity in an <inertial> with a warning only ("XML contains a
            # 'NaN'"), and its physics is then not a number: refused here, by link and attribute.
            for el, attrs in ((link.find("inertial/mass"), ("value",)),
                              (link.find("inertial/inertia"), ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")),
                              (link.find("inertial/origin"), ("xyz", "rpy"))):
                for k in attrs if el is not None else ():
                    text = el.get(k)
                    if text is None:
                        continue
                    try:
                        ok = all(math.isfinite(float(x)) for x in text.split()[:4])
                    except ValueError:
                        ok = False
                    if not ok:
                        raise ModelError(f"URDF {self.path}: link {str(name)[:80]!r}: <{el.tag} {k}>={text[:80]!r} "
                                         "is not finite numbers: MuJoCo would simulate it as NaN")
            inertia = link.find("inertial/inertia")
            if inertia is not None:
                a = {k: float(inertia.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
                m = np.array(
                    [[a["ixx"], a["ixy"], a["ixz"]], [a["ixy"], a["iyy"], a["iyz"]], [a["ixz"], a["iyz"], a["izz"]]]
                )
                low = np.linalg.eigvalsh(m).min()
                if low <= 0.0 and any(a[k] != 0.0 for k in ("ixy", "ixz", "iyz")):
                    for k in ("ixy", "ixz", "iyz"):
                        inertia.set(k, "0")
                    self.fixes.append({"link": name, "fix": f"inertia not positive definite (smallest principal "
                                       f"moment {low:.3g} kg m^2) made diagonal"})
        for old in root.findall("mujoco"):
            root.remove(old)
        mj = ET.SubElement(root, "mujoco")
        ET.SubElement(
            mj,
            "compiler",
            balanceinertia="true",
            boundmass="0.001",
            boundinertia="0.00001",
            discardvisual="false",
            fusestatic="false",
            strippath="false",
        )
        return ET.tostring(root, encoding="unicode")

    def _mesh_file(self, name):
        if not name:
            return None
        if name.startswith("package://"):
            pkg, _, rest = name[len("package://"):].partition("/")
            d = os.path.dirname(os.path.abspath(self.path))
            while d != os.path.dirname(d):
                if os.path.basename(d) == pkg:
                    f = os.path.join(d, rest)
                    return f if os.path.exists(f) else None
                d = os.path.dirname(d)
            return None
        f = name[len("file://"):] if name.startswith("file://") else name
        f = f if os.path.isabs(f) else os.path.join(os.path.dirname(self.path), f)
        return f if os.path.exists(f) else None


# ----- the robot in MuJoCo -----------------------------------------------------------------


def urdf_value(table_value, urdf, what):
    """A table entry: a number, or `urdf` for the URDF's own (which must be there)."""
    if table_value == "urdf":
        if not (isinstance(urdf, float) and math.isfinite(urdf) and urdf > 0.0):
            raise ModelError(f"{what}: the actuator table says `urdf`, but the URDF gives none")
        return urdf
    try:
        v = float(table_value)
    except (TypeError, ValueError):
        raise ModelError(f"{what}: {table_value!r} is neither a number nor `urdf`")
    if not (math.isfinite(v) and v > 0.0):
        raise ModelError(f"{what}: must be positive, got {v}")
    return v


def positive(table, section, key):
    v = table[section][key]
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not (math.isfinite(v) and v > 0):
        raise ModelError(f"actuator table: {section}.{key} must be a positive number, got {v!r}")
    return float(v)


class Robot:
    """The compiled model and what the plant reads and drives in it.

    `platform` is "unicycle" (the URDF's root link on its wheels) or "omni" (the URDF's root
    link mounted on a planar base at `mount` = (xyz, rpy)). `home` gives the chain's joints
    at the start (base first)."""

    def __init__(self, urdf_path, base_link, tip_link, platform, home, dt, table, mount=None, visuals=True):
        self.urdf = Urdf(urdf_path)
        self.table = table
        self.platform = platform
        self.dt = dt
        self.substeps = int(table["simulation"]["substeps"])
        if not 1 <= self.substeps <= 100:
            raise ModelError(f"actuator table: simulation.substeps must be 1 to 100, got {self.substeps}")
        self.chain_joints = self.urdf.chain(base_link, tip_link)
        if len(home) != len(self.chain_joints):
            raise ModelError(
                f"--home gives {len(home)} joints, the chain {base_link} -> {tip_link} of {self.urdf.path} has "
                f"{len(self.chain_joints)} ({', '.join(j['name'] for j in self.chain_joints)})"
            )
        for j, q in zip(self.chain_joints, home):
            if j["type"] != "continuous" and not (j["lower"] < q < j["upper"]):
                raise ModelError(f"--home: joint {j['name']} at {q} is outside its limits [{j['lower']}, {j['upper']}]")
        try:
            spec = mujoco.MjSpec.from_string(self.urdf.mujoco_xml(visuals))
        except ValueError as e:
            raise ModelError(f"MuJoCo cannot load {self.urdf.path}: {one_line(e)}")
        self.base_link, self.tip_link = base_link, tip_link
        names = set(j["name"] for j in self.chain_joints)
        if platform == "unicycle":
            if self.urdf.root_link != base_link:
                raise ModelError(
                    f"a wheeled base needs the base link to be the URDF's root: {base_link!r} is not "
                    f"({self.urdf.root_link!r} is)"
                )
            self.prefix = ""
            spec.body(base_link).add_freejoint(name="base")
            self.wheels = self._find_wheels(spec, names)
            self._contacts(spec)
        elif platform == "omni":
            self.prefix = "arm/"
            self.wheels = None
            self.casters = []
            spec = self._omni(spec, mount or ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
        else:
            raise ModelError(f"the MuJoCo plant drives a unicycle (wheeled) or omni base, not {platform!r}")
        spec.option.timestep = dt / self.substeps
        integrators = {
            "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
            "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
            "euler": mujoco.mjtIntegrator.mjINT_EULER,
            "rk4": mujoco.mjtIntegrator.mjINT_RK4,
        }
        if table["simulation"]["integrator"] not in integrators:
            raise ModelError(f"actuator table: simulation.integrator must be one of {sorted(integrators)}")
        spec.option.integrator = integrators[table["simulation"]["integrator"]]
        # The floor (a checker, 0.5 m squares, for the pictures) and the lights.
        spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                         rgb1=[0.92, 0.92, 0.92], rgb2=[0.8, 0.82, 0.86], width=256, height=256)
        grid = spec.add_material(name="grid", texrepeat=[1, 1], texuniform=True)
        grid.textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = "grid"
        spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                         rgb1=[0.75, 0.85, 0.95], rgb2=[1.0, 1.0, 1.0], width=64, height=64)
        floor = spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], material="grid")
        floor.friction = [float(x) for x in table["simulation"]["floor_friction"]]
        spec.worldbody.add_light(pos=[0, 0, 6], dir=[0, 0, -1], diffuse=[0.6, 0.6, 0.6])
        spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
        spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
        self._servos(spec, names)
        self._target_marker(spec)
        try:
            self.model = spec.compile()
        except ValueError as e:
            raise ModelError(f"MuJoCo cannot load {self.urdf.path}: {one_line(e)}")
        self.data = mujoco.MjData(self.model)
        self._index(home)
        self.fixes = self.urdf.fixes + self._bounded()
        self.mesh_fixes = self.urdf.mesh_fixes

    def _bounded(self):
        """What MuJoCo's compiler changed of the URDF's masses and inertias (its boundmass,
        boundinertia and balanceinertia, mujoco_xml's compiler element): each link whose
        <inertial> the model does not keep, by name, and how many links without one got a
        mass of their own."""
        m, out, massless = self.model, [], []
        for link in self.urdf.root.findall("link"):
            name = link.get("name")
            try:
                b = m.body(self.prefix + name).id
            except KeyError:
                continue
            inertial = link.find("inertial")
            mass_el = inertial.find("mass") if inertial is not None else None
            if mass_el is None:
                if m.body_mass[b] > 0.0:
                    massless.append(name)
                continue
            given = float(mass_el.get("value", "0"))
            if abs(m.body_mass[b] - given) > 1e-12 * max(1.0, abs(given)):
                out.append({"link": name, "fix": f"mass {given:g} -> {m.body_mass[b]:g} kg (MuJoCo's boundmass)"})
            el = inertial.find("inertia")
            if el is not None:
                a = {k: float(el.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
                if any(f["link"] == name and "made diagonal" in f["fix"] for f in self.urdf.fixes):
                    a.update(ixy=0.0, ixz=0.0, iyz=0.0)
                mat = np.array([[a["ixx"], a["ixy"], a["ixz"]], [a["ixy"], a["iyy"], a["iyz"]],
                                [a["ixz"], a["iyz"], a["izz"]]])
                was = np.sort(np.linalg.eigvalsh(mat))
                now = np.sort(np.array(m.body_inertia[b]))
                if np.abs(was - now).max() > 1e-9 * max(1.0, np.abs(was).max()):
                    out.append({"link": name, "fix": "principal inertia "
                                f"({', '.join(f'{x:.3g}' for x in was)}) -> ({', '.join(f'{x:.3g}' for x in now)}) "
                                "kg m^2 (MuJoCo's boundinertia, balanceinertia)"})
        if massless:
            out.append({"link": None, "fix": f"{len(massless)} links without <inertial> (frames: "
                        f"{', '.join(massless[:6])}{', …' if len(massless) > 6 else ''}) carry MuJoCo's smallest mass, "
                        "0.001 kg"})
        return out

    # -- building --

    def _find_wheels(self, spec, chain_names):
        """The two drive wheels: movable joints off the chain whose child link has a
        cylinder collision and whose axis lies along the base's y."""
        spec_tmp = spec.copy()
        try:
            m = spec_tmp.compile()
        except ValueError as e:
            raise ModelError(f"MuJoCo cannot load {self.urdf.path}: {one_line(e)}")
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        base = m.body(self.base_link).id
        rb = d.xmat[base].reshape(3, 3)
        found = []
        for j in self.urdf.joints.values():
            if j["name"] in chain_names or j["type"] not in ("continuous", "revolute"):
                continue
            link = self.urdf.links[j["child"]]
            cyl = [c for c in link.findall("collision") if c.find("geometry/cylinder") is not None]
            if not cyl:
                continue
            jid = m.joint(j["name"]).id
            axis_w = d.xaxis[jid]
            axis_b = rb.T @ axis_w
            if abs(axis_b[1]) < 0.99:
                continue
            pos_b = rb.T @ (d.xanchor[jid] - d.xpos[base])
            radius = float(cyl[0].find("geometry/cylinder").get("radius"))
            found.append({"joint": j["name"], "y": float(pos_b[1]), "z": float(pos_b[2]),
                          "sign": 1.0 if axis_b[1] > 0 else -1.0, "radius": radius,
                          "effort": j["effort"], "velocity": j["velocity"], "link": j["child"]})
        left = [w for w in found if w["y"] > 0]
        right = [w for w in found if w["y"] < 0]
        if len(left) != 1 or len(right) != 1:
            raise ModelError(
                f"a differential-drive base needs two drive wheels (joints off the arm's chain, axis along the "
                f"base's y, a cylinder collision), one on each side: {self.urdf.path} has "
                f"{[w['joint'] for w in found] or 'none'}"
            )
        left, right = left[0], right[0]
        if abs(left["radius"] - right["radius"]) > 1e-9:
            raise ModelError(f"wheels of different radii: {left['radius']} and {right['radius']}")
        return {"left": left, "right": right, "radius": left["radius"], "track": left["y"] - right["y"]}

    def _contacts(self, spec):
        """Only the wheels and the casters touch the floor; the casters without friction. A
        caster is a collision sphere (off the wheels) whose lowest point is on the floor at
        rest."""
        wheel_links = {self.wheels["left"]["link"], self.wheels["right"]["link"]}
        friction = float(self.table["wheels"]["caster_friction"])
        colliding = [g for g in spec.geoms if g.parent.name != "world" and g.contype != 0]
        for k, g in enumerate(colliding):
            if not g.name:
                g.name = f"collision/{g.parent.name}/{k}"
        try:
            m = spec.copy().compile()
        except ValueError as e:
            raise ModelError(f"MuJoCo cannot load {self.urdf.path}: {one_line(e)}")
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        self.casters = []
        for g in colliding:
            if g.parent.name in wheel_links:
                g.condim = 3
                continue
            gid = m.geom(g.name).id
            sphere = m.geom_type[gid] == mujoco.mjtGeom.mjGEOM_SPHERE
            if sphere and abs(d.geom_xpos[gid][2] - m.geom_size[gid][0]) < 2e-3:
                g.friction = [friction, 0.0, 0.0]
                g.condim = 1
                g.priority = 1
                self.casters.append(g.parent.name)
            else:
                g.contype = 0
                g.conaffinity = 0

    def _omni(self, spec, mount):
        """A planar base carrying the URDF's root link at `mount`; returns its spec."""
        arm = spec
        base = mujoco.MjSpec()
        size = [float(x) for x in self.table["omni"]["size"]]
        mass = positive(self.table, "omni", "mass")
        inertia = [mass / 12.0 * (size[1] ** 2 + size[2] ** 2), mass / 12.0 * (size[0] ** 2 + size[2] ** 2),
                   mass / 12.0 * (size[0] ** 2 + size[1] ** 2)]
        p = base.worldbody.add_body(name="platform", mass=mass, inertia=inertia, ipos=[0, 0, size[2] / 2])
        p.add_joint(name="base_x", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0])
        p.add_joint(name="base_y", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 1, 0])
        p.add_joint(name="base_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
        p.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[s / 2 for s in size], pos=[0, 0, size[2] / 2],
                   rgba=[0.35, 0.38, 0.45, 1], contype=0, conaffinity=0)
        p.add_site(name="drive")
        for n, gear in (("drive_forward", [1, 0, 0, 0, 0, 0]), ("drive_lateral", [0, 1, 0, 0, 0, 0]),
                        ("drive_yaw", [0, 0, 0, 0, 0, 1])):
            a = base.add_actuator(name=n, target="drive", trntype=mujoco.mjtTrn.mjTRN_SITE, gear=gear)
            angular = n == "drive_yaw"
            a.set_to_velocity(kv=1.0)  # set from the time constant once compiled (_gains)
            limit = positive(self.table, "omni", "torque" if angular else "force")
            a.forcelimited = True
            a.forcerange = [-limit, limit]
        (x, y, z), (r, pi, ya) = mount
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rpy_matrix(r, pi, ya).flatten())
        frame = p.add_frame(pos=[x, y, z], quat=list(quat))
        root = self.urdf.root_link
        if root == "world":
            kids = [j["child"] for j in self.urdf.joints.values() if j["parent"] == "world"]
            root = kids[0] if len(kids) == 1 else None
        if root is None or arm.body(root) is None:
            raise ModelError(f"URDF {self.urdf.path}: no single root link to mount on the omni base")
        if root != self.base_link:
            raise ModelError(f"an arm on the omni base is mounted by its root link {root!r}; --base-link is {self.base_link!r}")
        for g in arm.geoms:
            g.contype = 0
            g.conaffinity = 0
        frame.attach_body(arm.body(root), self.prefix, "")
        return base

    def _servos(self, spec, chain_names):
        t = self.table
        self.servo_joints = []
        for j in self.urdf.joints.values():
            if j["type"] not in MOVABLE:
                continue
            if self.wheels and j["name"] in (self.wheels["left"]["joint"], self.wheels["right"]["joint"]):
                continue
            over = t["joint"].get(j["name"], {})
            for k in over:
                if k not in ("kv", "effort", "speed", "armature"):
                    raise ModelError(f"actuator table: joint.{j['name']}.{k}: kv, effort, speed or armature")
            kv = float(over["kv"]) if "kv" in over else None
            effort = urdf_value(over.get("effort", t["arm"]["effort"]), j["effort"], f"joint {j['name']}: effort")
            speed = urdf_value(over.get("speed", t["arm"]["speed"]), j["velocity"], f"joint {j['name']}: speed")
            name = self.prefix + j["name"]
            armature = float(over.get("armature", t["arm"]["armature_prismatic" if j["type"] == "prismatic" else "armature"]))
            if not (math.isfinite(armature) and armature >= 0.0):
                raise ModelError(f"joint {j['name']}: armature must be a number >= 0, got {armature}")
            spec.joint(name).armature = armature
            a = spec.add_actuator(name="servo/" + j["name"], target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            a.set_to_velocity(kv=1.0)
            a.forcelimited = True
            a.forcerange = [-effort, effort]
            self.servo_joints.append({"joint": j["name"], "kv": kv, "effort": effort, "speed": speed,
                                      "chain": j["name"] in chain_names, "type": j["type"]})
        if self.wheels:
            w = t["wheels"]
            for side in ("left", "right"):
                wh = self.wheels[side]
                over = t["joint"].get(wh["joint"], {})
                wh["kv"] = float(over["kv"]) if "kv" in over else None
                wh["effort_limit"] = urdf_value(over.get("effort", w["effort"]), wh["effort"], f"wheel {wh['joint']}: effort")
                wh["speed_limit"] = urdf_value(over.get("speed", w["speed"]), wh["velocity"], f"wheel {wh['joint']}: speed")
                a = spec.add_actuator(name="wheel/" + side, target=wh["joint"], trntype=mujoco.mjtTrn.mjTRN_JOINT)
                a.set_to_velocity(kv=1.0)
                a.forcelimited = True
                a.forcerange = [-wh["effort_limit"], wh["effort_limit"]]

    def _target_marker(self, spec):
        b = spec.worldbody.add_body(name="target", mocap=True)
        b.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0], rgba=[0.9, 0.2, 0.1, 0.8],
                   contype=0, conaffinity=0, group=2)
        for axis, rgba in (([0.06, 0, 0], [1, 0, 0, 1]), ([0, 0.06, 0], [0, 0.8, 0, 1]), ([0, 0, 0.06], [0, 0, 1, 1])):
            b.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, 0] + axis, size=[0.004, 0, 0], rgba=rgba,
                       contype=0, conaffinity=0, group=2)
        spec.worldbody.add_camera(name="follow", mode=mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM, pos=[-2.2, -2.6, 1.9],
                                  xyaxes=[0.76, -0.65, 0, 0.3, 0.35, 0.89])

    def _index(self, home):
        m, d = self.model, self.data
        jid = lambda n: m.joint(self.prefix + n).id
        self.chain_names = [j["name"] for j in self.chain_joints]
        self.chain_qadr = np.array([m.jnt_qposadr[jid(n)] for n in self.chain_names])
        self.chain_dadr = np.array([m.jnt_dofadr[jid(n)] for n in self.chain_names])
        self.limits = [(j["lower"], j["upper"]) if j["type"] != "continuous" else (-math.inf, math.inf)
                       for j in self.chain_joints]
        servo = self.servo_joints
        self.servo_act = np.array([m.actuator("servo/" + s["joint"]).id for s in servo])
        self.servo_dof = np.array([m.jnt_dofadr[jid(s["joint"])] for s in servo])
        self.servo_qadr = np.array([m.jnt_qposadr[jid(s["joint"])] for s in servo])
        self.servo_speed = np.array([s["speed"] for s in servo])
        self.servo_chain = np.array([s["chain"] for s in servo])
        # Where each chain joint's servo is among the servos (the command's joint order).
        pos = {s["joint"]: i for i, s in enumerate(servo)}
        self.chain_servo = np.array([pos[n] for n in self.chain_names])
        self.hold = ~self.servo_chain
        self.gravity = bool(self.table["arm"]["gravity_compensation"])
        self.hold_gain = float(self.table["arm"]["hold_gain"])
        self.tool = m.body(self.prefix + self.tip_link).id
        self.target_mocap = m.body_mocapid[m.body("target").id]
        self.act_limit = np.array([m.actuator_forcerange[i][1] for i in range(m.nu)])
        self.act_names = [m.actuator(i).name for i in range(m.nu)]
        if self.platform == "unicycle":
            self.base = m.body(self.base_link).id
            self.free_q = m.jnt_qposadr[m.joint("base").id]
            self.free_d = m.jnt_dofadr[m.joint("base").id]
            w = self.wheels
            self.wheel_act = np.array([m.actuator("wheel/left").id, m.actuator("wheel/right").id])
            self.wheel_body = [m.body(w[s]["link"]).id for s in ("left", "right")]
            self.wheel_qadr = [m.jnt_qposadr[m.joint(w[s]["joint"]).id] for s in ("left", "right")]
            self.wheel_dof = [m.jnt_dofadr[m.joint(w[s]["joint"]).id] for s in ("left", "right")]
            self.wheel_sign = np.array([w["left"]["sign"], w["right"]["sign"]])
            self._contact_force = np.zeros(6)
            self.wheel_speed = min(w["left"]["speed_limit"], w["right"]["speed_limit"])
        else:
            self.base = m.body("platform").id
            self.omni_q = [m.jnt_qposadr[m.joint(n).id] for n in ("base_x", "base_y", "base_yaw")]
            self.omni_act = np.array([m.actuator(n).id for n in ("drive_forward", "drive_lateral", "drive_yaw")])
            self.omni_speed = (positive(self.table, "omni", "speed"), positive(self.table, "omni", "turn_rate"))
        # The start: the chain at home, every other joint at 0 (within its limits), the base at
        # the origin facing x, on the floor.
        mujoco.mj_resetData(m, d)
        for s, qa in zip(servo, self.servo_qadr):
            lo, hi = m.jnt_range[jid(s["joint"])]
            if m.jnt_limited[jid(s["joint"])] and not lo <= 0.0 <= hi:
                d.qpos[qa] = 0.5 * (lo + hi)
        d.qpos[self.chain_qadr] = home
        mujoco.mj_forward(m, d)
        self._gains()
        mujoco.mj_forward(m, d)
        self.hold_q = d.qpos[self.servo_qadr].copy()
        self.hold_idx = np.flatnonzero(self.hold)
        self.hold_qadr = self.servo_qadr[self.hold_idx]
        self.hold_target = self.hold_q[self.hold_idx]
        self.target = np.zeros(m.nu)  # each drive's target rate
        self.integral = np.zeros(m.nu)  # each drive's integral of its rate error (rate units)
        self.hold_act = self.servo_act[self.hold_idx]
        self.wheel_target = np.zeros(2)
        self.omni_target = np.zeros(3)
        self.clipped = 0  # commands clipped by a drive's speed limit (this period)

    def _gains(self):
        """Each velocity servo's gain kv from its time constant τ at the start: kv = I / τ,
        I the inertia the drive moves (the joint's diagonal of the mass matrix, its drive's
        armature included; for a wheel, also its half of the robot's mass at the wheel's
        radius) — a rate error decays as exp(−t/τ) until the effort limit. A table's kv
        wins."""
        m, d = self.model, self.data
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        self.gains = {}

        def put(act, kv, damping=0.0):
            # Force = kv ctrl − (kv − b) q̇: with the joint's passive damping −b q̇ the joint
            # feels kv (ctrl − q̇) — the damping compensated, implicitly, as the integrator
            # treats both (a feedforward of b q̇ one step old is unstable on a light link).
            m.actuator_gainprm[act][0] = kv
            m.actuator_biasprm[act][2] = -(kv - damping)
            self.gains[m.actuator(act).name] = kv

        tau = positive(self.table, "arm", "time_constant")
        for s, act, dof in zip(self.servo_joints, self.servo_act, self.servo_dof):
            s["kv"] = s["kv"] if s["kv"] is not None else full[dof, dof] / tau
            damping = float(m.dof_damping[dof]) if self.gravity else 0.0
            if s["kv"] < damping:
                raise ModelError(f"joint {s['joint']}: kv {s['kv']:.4g} is below the URDF's damping {damping}")
            put(act, s["kv"], damping)
        self.servo_inv_kv = np.array([1.0 / s["kv"] for s in self.servo_joints])
        self.servo_friction = np.array([float(m.dof_frictionloss[dof]) for dof in self.servo_dof])
        self.friction_ff = float(self.table["arm"].get("friction_feedforward", 1.0))
        if self.wheels:
            tau = positive(self.table, "wheels", "time_constant")
            carried = 0.5 * m.body_subtreemass[self.base] * self.wheels["radius"] ** 2
            for side, act, dof in zip(("left", "right"), self.wheel_act, self.wheel_dof):
                wh = self.wheels[side]
                wh["kv"] = wh["kv"] if wh["kv"] is not None else (full[dof, dof] + carried) / tau
                put(act, wh["kv"])
        else:
            tau = positive(self.table, "omni", "time_constant")
            # The drive's axes at the start are the joints' (the base faces x).
            for act, dof in zip(self.omni_act, (0, 1, 2)):
                put(act, full[dof, dof] / tau)
        kv = m.actuator_gainprm[:, 0]
        self.z_max = m.actuator_forcerange[:, 1] / kv
        self.ki_h = m.opt.timestep / positive(self.table, "simulation", "integral_time")

    # -- the kinematics the controller assumes, read from the model --

    def tool_in_base(self, q):
        """The tip link's pose seen from the base link with the chain at `q` and every other
        joint at the start: (R 3×3, p 3) — MuJoCo's forward kinematics of the URDF."""
        m = self.model
        d = mujoco.MjData(m)
        d.qpos[:] = self.data.qpos
        d.qpos[self.chain_qadr] = q
        if self.platform == "unicycle":
            d.qpos[self.free_q:self.free_q + 7] = [0, 0, 0, 1, 0, 0, 0]
        else:
            d.qpos[self.omni_q] = 0.0
        mujoco.mj_kinematics(m, d)
        rb, pb = d.xmat[self.base].reshape(3, 3), d.xpos[self.base]
        return rb.T @ d.xmat[self.tool].reshape(3, 3), rb.T @ (d.xpos[self.tool] - pb)

    # -- driving --

    def command(self, v, v_lat, omega, rates):
        """Sets the drives' targets for the command (v, v_lat, ω, joint rates); returns
        whether a drive's speed limit cut it."""
        clipped = False
        if self.wheels:
            r, b = self.wheels["radius"], self.wheels["track"]
            left, right = (v - omega * b / 2.0) / r, (v + omega * b / 2.0) / r
            top = max(abs(left), abs(right))
            if top > self.wheel_speed:
                k = self.wheel_speed / top
                left, right, clipped = left * k, right * k, True
            self.wheel_target[0] = left * self.wheel_sign[0]
            self.wheel_target[1] = right * self.wheel_sign[1]
            self.target[self.wheel_act] = self.wheel_target
        else:
            sp, tr = self.omni_speed
            k = max(abs(v) / sp, abs(v_lat) / sp, abs(omega) / tr, 1.0)
            clipped = k > 1.0
            self.omni_target[:] = (v / k, v_lat / k, omega / k)
            self.target[self.omni_act] = self.omni_target
        u = np.asarray(rates, dtype=float)
        lim = self.servo_speed[self.chain_servo]
        if np.any(np.abs(u) > lim):
            clipped = True
            u = np.clip(u, -lim, lim)
        self.target[self.servo_act[self.chain_servo]] = u
        return clipped

    def substep(self):
        """One physics step under the current targets. Every drive is a PI velocity servo:
        torque = kv (target − rate) + kv z + feedforward, z the integral of the rate error
        over the integral time (anti-windup: |kv z| within the effort), the feedforward the
        model's bias forces (gravity, Coriolis) of the previous step and the URDF's friction in
        the commanded direction, for the arm's joints."""
        d = self.data
        target = self.target
        if len(self.hold_idx):
            target[self.hold_act] = self.hold_gain * (self.hold_target - d.qpos[self.hold_qadr])
        z = self.integral
        z += self.ki_h * (target - d.actuator_velocity)
        np.clip(z, -self.z_max, self.z_max, out=z)
        ctrl = target + z
        if self.gravity:
            u = target[self.servo_act]
            ff = d.qfrc_bias[self.servo_dof] + self.friction_ff * self.servo_friction * np.tanh(u * FRICTION_RATE)
            ctrl[self.servo_act] += ff * self.servo_inv_kv
        d.ctrl[:] = ctrl
        mujoco.mj_step(self.model, d)

    # -- measuring --

    def base_pose(self):
        """(x, y, yaw) of the base link (yaw in (−π, π])."""
        d = self.data
        if self.wheels:
            r = d.xmat[self.base]
            p = d.xpos[self.base]
            return float(p[0]), float(p[1]), math.atan2(r[3], r[0])
        q = d.qpos
        return float(q[self.omni_q[0]]), float(q[self.omni_q[1]]), float(q[self.omni_q[2]])

    def joints(self):
        return self.data.qpos[self.chain_qadr].tolist()

    def tool_pose(self):
        """The tip link's pose in the world: (R as 9 numbers row by row, p)."""
        d = self.data
        return tuple(d.xmat[self.tool].tolist()), tuple(d.xpos[self.tool].tolist())

    def base_velocity(self):
        """The base's true forward and lateral speed (m/s) and turn rate (rad/s)."""
        d = self.data
        r = d.xmat[self.base]
        c, s = r[0], r[3]
        n = math.hypot(c, s)
        c, s = c / n, s / n
        if self.wheels:
            vx, vy = d.qvel[self.free_d], d.qvel[self.free_d + 1]
            # The free joint's angular velocity is in the body's frame: its world z component.
            wz = float(r[6] * d.qvel[self.free_d + 3] + r[7] * d.qvel[self.free_d + 4] + r[8] * d.qvel[self.free_d + 5])
        else:
            vx, vy = d.qvel[0], d.qvel[1]
            wz = float(d.qvel[2])
        return float(c * vx + s * vy), float(-s * vx + c * vy), wz

    def wheel_slip(self, out):
        """Each drive wheel's slip speed (m/s): the horizontal speed of its lowest point, which
        is 0 while it rolls without slipping (left, right) into `out`."""
        m, d = self.model, self.data
        v6 = np.zeros(6)
        for i, b in enumerate(self.wheel_body):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, v6, 0)
            w, v = v6[:3], v6[3:]
            rr = self.wheels["radius"]
            # The contact point below the wheel's centre: v + ω × (0, 0, −R).
            out[i] = math.hypot(v[0] - w[1] * rr, v[1] + w[0] * rr)

    def wheel_traction(self, out):
        """How much of its friction each drive wheel uses (left, right) into `out`: the net
        tangential force of its contacts over μ times their net normal force. The cylinder
        touches the floor at its two rims, whose forces also push against each other when the
        wheel turns about the vertical (scrub, internal to the wheel): the net is the wheel's
        traction on the floor. 1 means it is at its limit: the wheel slides. Below it the
        wheel still creeps (MuJoCo's soft contacts, as a tyre does) — the slip speed counts
        that too."""
        m, d = self.model, self.data
        f = self._contact_force
        tangential = np.zeros((2, 3))
        normal = np.zeros(2)
        mu = np.zeros(2)
        for i in range(d.ncon):
            c = d.contact[i]
            for side, body in enumerate(self.wheel_body):
                if m.geom_bodyid[c.geom1] == body or m.geom_bodyid[c.geom2] == body:
                    mujoco.mj_contactForce(m, d, i, f)
                    frame = c.frame.reshape(3, 3)  # rows: the normal, two tangents
                    tangential[side] += f[1] * frame[1] + f[2] * frame[2]
                    normal[side] += f[0]
                    mu[side] = c.friction[0]
        for side in range(2):
            out[side] = np.linalg.norm(tangential[side]) / (mu[side] * normal[side]) if normal[side] > 0 else 0.0

    def wheel_angles(self):
        return [float(self.data.qpos[a]) for a in self.wheel_qadr]

    def set_target_marker(self, rotation, position):
        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, np.asarray(rotation, dtype=float))
        self.data.mocap_pos[self.target_mocap] = position
        self.data.mocap_quat[self.target_mocap] = q
