"""`dnb_split`: a Mitsuba 3 path tracer that splits each sample's radiance the way a harness frame
does (docs/design.md, "AOV frame file": F = (D + I) * T + R + E), for the mitsuba back-end
(mitsuba_backend.py; docs/renderers.md).

    <integrator type="dnb_split"><integer name="max_depth" value="8"/></integrator>

Parameters: `max_depth` (path length in segments, the camera ray included, as Mitsuba's `path`
and the harness's tracer count it; 1 shows emitters only), `rr_depth` (Russian roulette from
this depth on, default 5, as `path`).

The estimator is Mitsuba's `path` (src/integrators/path.cpp: next-event estimation and BSDF
sampling combined by the power heuristic, Russian roulette), written per sample for the
scalar variants. Each sample's contributions go to one of four sums, by where the path left the
first surface it hit:
  E  emitted radiance seen directly (an emitter hit by the camera ray, or the environment);
  DT light reaching the first hit straight from an emitter through its diffuse lobe: the
     light-sampled part through the diffuse lobe alone, and an emitter hit by a BSDF sample
     of the diffuse lobe;
  IT every later contribution of a path whose first bounce sampled the diffuse lobe;
  R  the rest: the light-sampled part through the other lobes (glossy, the coat of a plastic),
     and every contribution of a path whose first bounce sampled a non-diffuse lobe.
Their sum is the sample's radiance, so per sample F = DT + IT + R + E exactly. T (the
diffuse reflectance, `eval_diffuse_reflectance`, 0 on a BSDF without a diffuse lobe), the
world-space shading normal (facing the camera) and the distance to the first hit are AOVs too.
The back-end divides the pixel means: D = mean(DT) / mean(T), I = mean(IT) / mean(T), the
albedo-weighted means the harness's tracer stores, so that (D + I) * T + R + E is the pixel's
colour up to rounding.

Limits: a BSDF sample of the diffuse lobe carries the whole BSDF's value in the direction it
chose (Mitsuba's `sample` returns f / pdf of every non-delta lobe together), so on a rough
plastic a little glossy light lands in D and I and a little diffuse light in R; the sum is
unbiased and the split exact per sample, only the share between the layers is approximate
there. Pure diffuse, conductor and dielectric surfaces split exactly. No participating media.
"""

import importlib

import drjit as dr

AOVS = (["direct_t." + c for c in "RGB"] + ["indirect_t." + c for c in "RGB"] + ["albedo." + c for c in "RGB"]
        + ["reflection." + c for c in "RGB"] + ["emission." + c for c in "RGB"] + ["normal." + c for c in "XYZ"]
        + ["depth.Z"])


def _mis(a, b):
    """The power heuristic's weight of a strategy of density a against one of density b."""
    a2 = a * a
    d = a2 + b * b
    return a2 / d if d > 0 else 0.0


def integrator_class(mi):
    """The integrator's class for `mi`, a variant's module (mitsuba.scalar_rgb): Mitsuba's variant
    is set per thread, and its render threads call sample(), so the class names the variant's
    types through this module, never through the `mitsuba` package."""

    class SplitIntegrator(mi.SamplingIntegrator):
        def __init__(self, props):
            super().__init__(props)
            self.max_depth = props.get("max_depth", 8)
            self.rr_depth = props.get("rr_depth", 5)
            if self.max_depth < 1:
                raise ValueError(f"dnb_split: max_depth must be at least 1, got {self.max_depth}")

        def aov_names(self):
            return AOVS

        def sample(self, scene, sampler, ray, medium=None, active=True):
            black = mi.Color3f(0.0)
            dt, it, refl, emis, albedo = mi.Color3f(0.0), mi.Color3f(0.0), mi.Color3f(0.0), mi.Color3f(0.0), mi.Color3f(0.0)
            normal, depth = mi.Vector3f(0.0), 0.0
            ctx = mi.BSDFContext()
            diffuse_ctx = mi.BSDFContext(mi.TransportMode.Radiance, int(mi.BSDFFlags.Diffuse), 0xFFFFFFFF)  # every component of the diffuse lobes
            throughput = mi.Color3f(1.0)
            eta = 1.0
            first_diffuse = False  # the first bounce sampled the diffuse lobe
            prev_si, prev_pdf, prev_delta = None, 1.0, True
            ray = mi.Ray3f(ray)
            si = scene.ray_intersect(ray)
            bounce = 0
            while True:
                # An emitter hit (or the environment on a miss), weighted against its light sample.
                emitter = si.emitter(scene)
                if emitter is not None:
                    le = emitter.eval(si)
                    if bounce == 0:
                        emis += le
                    else:
                        w = 1.0
                        if not prev_delta:
                            ds = mi.DirectionSample3f(scene, si, prev_si)
                            w = _mis(prev_pdf, scene.pdf_emitter_direction(prev_si, ds, True))
                        c = throughput * le * w
                        if not first_diffuse:
                            refl += c
                        elif bounce == 1:
                            dt += c
                        else:
                            it += c
                if not si.is_valid() or bounce + 1 >= self.max_depth:
                    break
                bsdf = si.bsdf(ray)
                flags = bsdf.flags()
                if bounce == 0:
                    n = mi.Vector3f(si.sh_frame.n)
                    normal = -n if dr.dot(n, ray.d) > 0 else n
                    depth = si.t
                    if mi.has_flag(flags, mi.BSDFFlags.Diffuse):
                        albedo = mi.Color3f(bsdf.eval_diffuse_reflectance(si))
                # Next-event estimation (a light sample), unless every lobe is a delta.
                if mi.has_flag(flags, mi.BSDFFlags.Smooth):
                    ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(), True)
                    if ds.pdf != 0:
                        wo = si.to_local(ds.d)
                        f, pdf = bsdf.eval_pdf(ctx, si, wo)
                        w = 1.0 if ds.delta else _mis(ds.pdf, pdf)
                        c = throughput * em_weight * f * w
                        if bounce == 0:
                            fd = bsdf.eval(diffuse_ctx, si, wo)
                            cd = throughput * em_weight * fd * w
                            dt += cd
                            refl += c - cd
                        elif first_diffuse:
                            it += c
                        else:
                            refl += c
                # The next direction, from the whole BSDF.
                bs, weight = bsdf.sample(ctx, si, sampler.next_1d(), sampler.next_2d())
                if bs.pdf <= 0 or weight == black:
                    break
                if bounce == 0:
                    first_diffuse = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Diffuse)
                throughput *= weight
                eta *= bs.eta
                prev_si, prev_pdf = si, bs.pdf
                prev_delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
                ray = si.spawn_ray(si.to_world(bs.wo))
                si = scene.ray_intersect(ray)
                bounce += 1
                # Russian roulette, as Mitsuba's path: on the throughput with the radiance scale of
                # refraction taken out.
                if bounce >= self.rr_depth:
                    q = min(mi.luminance(throughput) * eta * eta, 0.95)
                    if sampler.next_1d() >= q:
                        break
                    throughput /= q
            total = dt + it + refl + emis
            aovs = [dt[0], dt[1], dt[2], it[0], it[1], it[2], albedo[0], albedo[1], albedo[2], refl[0], refl[1], refl[2],
                    emis[0], emis[1], emis[2], normal[0], normal[1], normal[2], depth]
            return total, True, aovs


    return SplitIntegrator


def register(variant):
    mi = importlib.import_module("mitsuba." + variant)
    cls = integrator_class(mi)
    mi.register_integrator("dnb_split", lambda props: cls(props))
