"""The tracer's materials and sky as Cycles node trees (renderers/cycles, docs/renderers.md,
"Blender Cycles"). `denoisebench export-gltf` writes each material's exact parameters in its
glTF extras (tracer/gltf_export.h); Blender's glTF importer keeps extras as custom properties,
and build_material() replaces the imported (nearest metallic-roughness) node tree by:

  diffuse     Diffuse BSDF (albedo, times the baked texture where there is one)        exact
  mirror      sharp Glossy BSDF, colour = tint                                         exact
  coated      Mix(Schlick F(n.wo) of ior; Diffuse(albedo), sharp Glossy(tint))          exact
  conductor   Glossy (sharp, or GGX of roughness sqrt(alpha)), colour = the complex-index
              Fresnel of (eta, k) times tint, or Schlick from F0 = tint, at the macro normal's
              cos(n.wo)                                    exact when smooth; rough: F at n, not h
  dielectric  Glass BSDF (tint = transmittance) or Mix(Fresnel(ior); Refraction(transmittance),
              Glossy(tint)); absorption: a Volume Absorption of the same Beer coefficient
                                                           exact when smooth; rough: approximate
  thin        Mix(2R/(1+R), R the dielectric Fresnel of ior at cos(n.wo); Transparent(transmittance),
              sharp Glossy(tint)): a thin sheet, approximate: Cycles' transparent surface is not a
              bounce (the tracer counts the crossing as a vertex) and lets shadow rays through
              (the tracer's next-event rays stop at glass)
  plastic     Mix(F dielectric(ior) at cos(n.wo); Diffuse(albedo), Glossy(tint, roughness
              sqrt(alpha))): approximate (the tracer's plastic also keeps the light the coat
              reflects back into the base, and attenuates by the coat on the way in and out)
  emission    an Emission shader added, strength 1 - Backfacing (front face only) unless
              two_sided                                                               exact

Sky (scenes[0].extras.denoisebench): `sky` a constant Background; `sky_gradient` {zenith,
horizon, ground, up} the tracer's own blend (tracer/scene.cpp, Sky::radiance) built from the
background's direction: horizon + (zenith - horizon) sqrt(max(c, 0)) + (ground - horizon)
min(1, 4 max(-c, 0)), c = dot(dir, up): exact.
"""
import math

import bpy

# glTF's Y-up to Blender's Z-up, as Blender's importer converts: (x, y, z) -> (x, -z, y).
def gltf_to_blender(v):
    return (v[0], -v[2], v[1])


class Graph:
    """Scalar arithmetic on shader sockets: constants fold in Python, the rest become Math nodes."""

    def __init__(self, tree):
        self.tree = tree

    def node(self, kind, **props):
        n = self.tree.nodes.new(kind)
        for k, v in props.items():
            setattr(n, k, v)
        return n

    def link(self, value, socket):
        if isinstance(value, (int, float)):
            socket.default_value = float(value)
        elif isinstance(value, (tuple, list)):
            socket.default_value = tuple(value) + ((1.0,) if len(socket.default_value) == 4 and len(value) == 3 else ())
        else:
            self.tree.links.new(value, socket)

    def math(self, op, a, b=None):
        consts = {"ADD": lambda x, y: x + y, "SUBTRACT": lambda x, y: x - y, "MULTIPLY": lambda x, y: x * y,
                  "DIVIDE": lambda x, y: x / y, "POWER": lambda x, y: x ** y, "MAXIMUM": max, "MINIMUM": min,
                  "SQRT": lambda x, y: math.sqrt(x)}
        if isinstance(a, (int, float)) and (b is None or isinstance(b, (int, float))):
            return float(consts[op](a, b))
        n = self.node("ShaderNodeMath", operation=op, use_clamp=False)
        self.link(a, n.inputs[0])
        if b is not None:
            self.link(b, n.inputs[1])
        return n.outputs[0]

    def add(self, a, b): return self.math("ADD", a, b)
    def sub(self, a, b): return self.math("SUBTRACT", a, b)
    def mul(self, a, b): return self.math("MULTIPLY", a, b)
    def div(self, a, b): return self.math("DIVIDE", a, b)
    def sqrt(self, a): return self.math("SQRT", a)
    def clamp01(self, a): return self.math("MINIMUM", self.math("MAXIMUM", a, 0.0), 1.0)

    def rgb(self, r, g, b):
        if all(isinstance(c, (int, float)) for c in (r, g, b)):
            return (float(r), float(g), float(b))
        n = self.node("ShaderNodeCombineColor")
        for i, c in enumerate((r, g, b)):
            self.link(c, n.inputs[i])
        return n.outputs[0]

    def cos_wo(self):
        """|dot(n, wo)| at the shading point (Layer Weight's Facing is 1 - |dot(n, I)| at blend 0.5)."""
        lw = self.node("ShaderNodeLayerWeight")
        lw.inputs["Blend"].default_value = 0.5
        return self.clamp01(self.sub(1.0, lw.outputs["Facing"]))

    # ---- Fresnel terms, as tracer/bsdf.cpp and tracer/scene.h compute them ----
    def schlick(self, c, r0):
        m = self.sub(1.0, c)
        m2 = self.mul(m, m)
        return self.add(r0, self.mul(1.0 - r0, self.mul(self.mul(m2, m2), m)))

    def dielectric(self, c, eta):
        """Unpolarised Fresnel reflectance entering a medium of relative index eta (> 0) at cos c."""
        sin2_t = self.div(self.sub(1.0, self.mul(c, c)), eta * eta)
        cos_t = self.sqrt(self.math("MAXIMUM", self.sub(1.0, sin2_t), 0.0))
        rs = self.div(self.sub(c, self.mul(eta, cos_t)), self.add(c, self.mul(eta, cos_t)))
        rp = self.div(self.sub(self.mul(eta, c), cos_t), self.add(self.mul(eta, c), cos_t))
        return self.mul(0.5, self.add(self.mul(rs, rs), self.mul(rp, rp)))

    def conductor(self, c, eta, k):
        """pbrt's complex-index Fresnel of one channel at cos c."""
        cos2 = self.mul(c, c)
        sin2 = self.sub(1.0, cos2)
        t0 = self.sub(eta * eta - k * k, sin2)
        a2b2 = self.sqrt(self.add(self.mul(t0, t0), 4 * eta * eta * k * k))
        t1 = self.add(a2b2, cos2)
        a = self.sqrt(self.mul(0.5, self.add(a2b2, t0)))
        t2 = self.mul(self.mul(2.0, c), a)
        rs = self.div(self.sub(t1, t2), self.add(t1, t2))
        t3 = self.add(self.mul(cos2, a2b2), self.mul(sin2, sin2))
        t4 = self.mul(t2, sin2)
        rp = self.mul(rs, self.div(self.sub(t3, t4), self.add(t3, t4)))
        return self.mul(0.5, self.add(rp, rs))


def _rgb(v, name):
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise ValueError(f"extras.denoisebench.{name}: expected [r, g, b], got {v!r}")
    return tuple(float(x) for x in v)


def _roughness(alpha):
    return math.sqrt(max(0.0, alpha))  # GGX alpha = Blender's roughness squared


def _glossy(g, colour, alpha):
    smooth = alpha < 1e-3  # the tracer treats such a lobe as a delta (tracer/bsdf.h, Ggx::smooth)
    n = g.node("ShaderNodeBsdfGlossy", distribution="SHARP" if smooth else "GGX")
    g.link(colour, n.inputs["Color"])
    n.inputs["Roughness"].default_value = 0.0 if smooth else _roughness(alpha)
    return n.outputs[0]


def _mix(g, fac, a, b):
    """(1 - fac) a + fac b."""
    n = g.node("ShaderNodeMixShader")
    g.link(fac, n.inputs[0])
    g.tree.links.new(a, n.inputs[1])
    g.tree.links.new(b, n.inputs[2])
    return n.outputs[0]


def _diffuse(g, colour):
    n = g.node("ShaderNodeBsdfDiffuse")
    g.link(colour, n.inputs["Color"])
    n.inputs["Roughness"].default_value = 0.0
    return n.outputs[0]


def build_material(mat, exact):
    """Replaces mat's node tree by the tracer's material `exact` (extras.denoisebench)."""
    kind = exact.get("type")
    tree = mat.node_tree
    # The imported base colour (the baked texture times the factor) where the material has a texture.
    textured = None
    if "texture" in exact:
        for link in tree.links:
            if link.to_node.bl_idname == "ShaderNodeBsdfPrincipled" and link.to_socket.name == "Base Color":
                textured = link.from_socket
    keep = set()
    if textured is not None:  # the texture and what feeds it (UV map, mapping)
        todo = [textured.node]
        while todo:
            n = todo.pop()
            keep.add(n.name)
            todo += [l.from_node for l in tree.links if l.to_node == n]
    for n in list(tree.nodes):
        if n.name not in keep:
            tree.nodes.remove(n)
    g = Graph(tree)
    out = g.node("ShaderNodeOutputMaterial", target="CYCLES")
    albedo = _rgb(exact.get("albedo", [0.8, 0.8, 0.8]), "albedo")
    tint = _rgb(exact.get("tint", [1, 1, 1]), "tint")
    # With a texture, the importer's base colour is already baseColorFactor (= albedo) times it.
    base = albedo if textured is None else textured
    alpha = float(exact.get("alpha", 0.0))
    ior = float(exact.get("ior", 1.5))
    surface, volume = None, None
    if kind == "diffuse":
        surface = _diffuse(g, base)
    elif kind == "mirror":
        surface = _glossy(g, tint, 0.0)
    elif kind == "coated":
        r0 = ((ior - 1) / (ior + 1)) ** 2
        surface = _mix(g, g.schlick(g.cos_wo(), r0), _diffuse(g, base), _glossy(g, tint, 0.0))
    elif kind == "plastic":
        surface = _mix(g, g.dielectric(g.cos_wo(), ior), _diffuse(g, base), _glossy(g, tint, alpha))
    elif kind == "conductor":
        c = g.cos_wo()
        if exact.get("schlick"):
            f = g.rgb(*(g.schlick(c, t) for t in tint))
        else:
            eta, k = _rgb(exact.get("eta"), "eta"), _rgb(exact.get("k"), "k")
            f = g.rgb(*(g.mul(g.conductor(c, eta[i], k[i]), tint[i]) for i in range(3)))
        surface = _glossy(g, f, alpha)
    elif kind == "dielectric":
        trans = _rgb(exact.get("transmittance", [1, 1, 1]), "transmittance")
        if exact.get("thin"):
            r = g.dielectric(g.cos_wo(), ior)
            fac = g.div(g.mul(2.0, r), g.add(1.0, r))
            t = g.node("ShaderNodeBsdfTransparent")
            g.link(trans, t.inputs["Color"])
            surface = _mix(g, fac, t.outputs[0], _glossy(g, tint, 0.0))
        else:
            smooth = alpha < 1e-3
            dist = "SHARP" if smooth else "GGX"
            if tint == trans:
                n = g.node("ShaderNodeBsdfGlass", distribution=dist)
                g.link(trans, n.inputs["Color"])
                n.inputs["Roughness"].default_value = 0.0 if smooth else _roughness(alpha)
                n.inputs["IOR"].default_value = ior
                surface = n.outputs[0]
            else:
                fr = g.node("ShaderNodeFresnel")
                fr.inputs["IOR"].default_value = ior
                rf = g.node("ShaderNodeBsdfRefraction", distribution=dist)
                g.link(trans, rf.inputs["Color"])
                rf.inputs["Roughness"].default_value = 0.0 if smooth else _roughness(alpha)
                rf.inputs["IOR"].default_value = ior
                surface = _mix(g, fr.outputs[0], rf.outputs[0], _glossy(g, tint, alpha))
            absorption = _rgb(exact.get("absorption", [0, 0, 0]), "absorption")
            density = max(absorption)
            if density > 0:  # Cycles: sigma_a = (1 - colour) density
                v = g.node("ShaderNodeVolumeAbsorption")
                v.inputs["Color"].default_value = (*(1 - a / density for a in absorption), 1.0)
                v.inputs["Density"].default_value = density
                volume = v.outputs[0]
    else:
        raise ValueError(f"extras.denoisebench.type '{kind}' is not one the cycles back-end knows "
                         "(diffuse, mirror, coated, plastic, conductor, dielectric)")
    emission = exact.get("emission")
    if emission is not None and max(_rgb(emission, "emission")) > 0:
        e = g.node("ShaderNodeEmission")
        g.link(_rgb(emission, "emission"), e.inputs["Color"])
        if not exact.get("two_sided"):
            geo = g.node("ShaderNodeNewGeometry")
            g.link(g.sub(1.0, geo.outputs["Backfacing"]), e.inputs["Strength"])
        else:
            e.inputs["Strength"].default_value = 1.0
        add = g.node("ShaderNodeAddShader")
        tree.links.new(surface, add.inputs[0])
        tree.links.new(e.outputs[0], add.inputs[1])
        surface = add.outputs[0]
    tree.links.new(surface, out.inputs["Surface"])
    if volume is not None:
        tree.links.new(volume, out.inputs["Volume"])
    mat.blend_method = "OPAQUE"


def build_world(scene, extras):
    """The world from the scene's extras.denoisebench: a constant sky, a gradient sky, or black."""
    world = scene.world or bpy.data.worlds.new("denoisebench sky")
    scene.world = world
    world.use_nodes = True
    tree = world.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    g = Graph(tree)
    out = g.node("ShaderNodeOutputWorld", target="CYCLES")
    bg = g.node("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 1.0
    tree.links.new(bg.outputs[0], out.inputs["Surface"])
    if "sky_gradient" in extras:
        s = extras["sky_gradient"]
        zenith, horizon, ground = (_rgb(s.get(k), f"sky_gradient.{k}") for k in ("zenith", "horizon", "ground"))
        up = gltf_to_blender(_rgb(s.get("up", [0, 1, 0]), "sky_gradient.up"))
        tc = g.node("ShaderNodeTexCoord")  # Generated, in a world shader: the ray's direction
        dot = g.node("ShaderNodeVectorMath", operation="DOT_PRODUCT")
        tree.links.new(tc.outputs["Generated"], dot.inputs[0])
        dot.inputs[1].default_value = up
        c = dot.outputs["Value"]
        w_up = g.sqrt(g.math("MAXIMUM", c, 0.0))
        w_down = g.math("MINIMUM", g.mul(g.math("MAXIMUM", g.sub(0.0, c), 0.0), 4.0), 1.0)
        colour = g.rgb(*(g.add(horizon[i], g.add(g.mul(zenith[i] - horizon[i], w_up), g.mul(ground[i] - horizon[i], w_down)))
                         for i in range(3)))
        g.link(colour, bg.inputs["Color"])
    elif "sky" in extras:
        bg.inputs["Color"].default_value = (*_rgb(extras["sky"], "sky"), 1.0)
    else:
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        bg.inputs["Strength"].default_value = 0.0
