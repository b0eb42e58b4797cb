#include "core/exr_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_edges.h"
#include "core/exr_header.h"
#include "core/hash.h"
#include "core/memory_budget.h"

namespace dnb {
namespace fs = std::filesystem;
using OIIO::TypeDesc;
using exr::open_input;

static const char* kAttrPrefix = "denoisebench:";
static const char* kExtraPrefix = "denoisebench:extra:";

std::string edges_path(const std::string& frame_path) {
  fs::path p(frame_path);
  return (p.parent_path() / (p.stem().string() + ".edges" + p.extension().string())).string();
}

namespace {

void put_meta(OIIO::ImageSpec& spec, const FrameMeta& m, int width, int height,
              std::size_t edge_pixels) {
  spec.attribute(std::string(kAttrPrefix) + "scene", m.scene);
  spec.attribute(std::string(kAttrPrefix) + "spp", m.spp);
  spec.attribute(std::string(kAttrPrefix) + "size", fmt::format("{}x{}", width, height));
  spec.attribute(std::string(kAttrPrefix) + "seed", std::to_string(m.seed));
  spec.attribute(std::string(kAttrPrefix) + "tracer_version", m.tracer_version);
  spec.attribute(std::string(kAttrPrefix) + "build_version", m.build_version);
  spec.attribute(std::string(kAttrPrefix) + "render_seconds", fmt::format("{:.17g}", m.render_seconds));
  spec.attribute(std::string(kAttrPrefix) + "dropped_samples", std::to_string(m.dropped_samples));
  spec.attribute(std::string(kAttrPrefix) + "reflection_levels", m.reflection_levels);
  spec.attribute(std::string(kAttrPrefix) + "edge_pixels", std::to_string(edge_pixels));
  for (auto& [k, v] : m.extra) spec.attribute(std::string(kExtraPrefix) + k, v);
}

std::string attr_string(const OIIO::ImageSpec& spec, const std::string& name) {
  return std::string(spec.get_string_attribute(std::string(kAttrPrefix) + name));
}

FrameMeta get_meta(const OIIO::ImageSpec& spec, std::size_t* edge_pixels) {
  FrameMeta m;
  m.scene = attr_string(spec, "scene");
  m.spp = spec.get_int_attribute(std::string(kAttrPrefix) + "spp", 0);
  try {
    std::string s = attr_string(spec, "seed");
    m.seed = s.empty() ? 0 : std::stoull(s);
    s = attr_string(spec, "render_seconds");
    m.render_seconds = s.empty() ? 0.0 : std::stod(s);
    s = attr_string(spec, "dropped_samples");
    m.dropped_samples = s.empty() ? 0 : std::stoll(s);
    s = attr_string(spec, "edge_pixels");
    *edge_pixels = s.empty() ? 0 : std::stoull(s);
  } catch (const std::exception&) {
    throw InputError("malformed denoisebench metadata (seed, render_seconds, dropped_samples or edge_pixels)");
  }
  m.tracer_version = attr_string(spec, "tracer_version");
  m.build_version = attr_string(spec, "build_version");
  m.reflection_levels = spec.get_int_attribute(std::string(kAttrPrefix) + "reflection_levels", 0);
  const std::string extra = kExtraPrefix;
  for (const auto& p : spec.extra_attribs) {
    std::string n = p.name().string();
    if (n.rfind(extra, 0) == 0) m.extra[n.substr(extra.size())] = p.get_string();
  }
  return m;
}


// Layer of an EXR channel name: "R" -> color, "direct.R" -> direct, "refl1.normal.X" -> refl1.normal.
std::string layer_of(const std::string& channel) {
  auto dot = channel.rfind('.');
  return dot == std::string::npos ? std::string(layer::kColor) : channel.substr(0, dot);
}

// An OpenImageIO output stream into an AtomicOutput's temporary file: every write goes through
// AtomicOutput::write_at (checked, with the system's reason kept for the error message).
// OpenEXR's own file writer can lose data to a full disk and still close successfully (a
// 4096-byte unreadable frame with exit status 0). Encoding into memory first, as this did
// before, held the whole encoded image: a 1920x1080 frame's 370 MB, twice that while the vector
// grew.
class AtomicProxy final : public OIIO::Filesystem::IOProxy {
 public:
  explicit AtomicProxy(AtomicOutput& out) : IOProxy("", Write), out_(out) {}
  const char* proxytype() const override { return "denoisebench-atomic"; }
  size_t write(const void* buf, size_t size) override {
    const size_t n = pwrite(buf, size, m_pos);
    m_pos += int64_t(n);
    return n;
  }
  size_t pwrite(const void* buf, size_t size, int64_t offset) override {
    if (!error_.empty() || offset < 0) return 0;
    try {
      out_.write_at(buf, size, std::uint64_t(offset));
    } catch (const WorkError& e) {
      error_ = e.what();  // OpenImageIO sees a short write and fails; the caller reports this
      return 0;
    }
    end_ = std::max(end_, std::uint64_t(offset) + size);
    return size;
  }
  size_t size() const override { return size_t(end_); }
  const std::string& error() const { return error_; }

 private:
  AtomicOutput& out_;
  std::uint64_t end_ = 0;
  std::string error_;
};

// The image written to its temporary file by `write_pixels` (every byte checked, fsynced), not
// yet committed.
template <class WriteFn>
std::unique_ptr<AtomicOutput> stage_image_with(const std::string& path, OIIO::ImageSpec spec, const char* compression,
                                               WriteFn&& write_pixels) {
  auto out = std::make_unique<AtomicOutput>(path);
  spec.attribute("compression", compression);
  // Declared before the writer, so that it outlives it: a writer destroyed after a failure
  // closes its file and still writes through the proxy (ASan: a use after free otherwise).
  AtomicProxy proxy(*out);
  auto o = OIIO::ImageOutput::create(out->temp_path());
  if (!o) throw WorkError(fmt::format("'{}': no image writer: {}", path, OIIO::geterror()));
  if (!o->supports("ioproxy")) throw WorkError(fmt::format("'{}': the {} writer cannot stream", path, o->format_name()));
  const bool ok = o->set_ioproxy(&proxy) && o->open(out->temp_path(), spec) && write_pixels(*o) && o->close();
  if (!proxy.error().empty()) throw WorkError(proxy.error());  // the system's reason (a full disk)
  if (!ok) throw WorkError(fmt::format("'{}': write failed: {}", path, o->geterror()));
  o.reset();
  out->finish_writes();
  return out;
}

std::unique_ptr<AtomicOutput> stage_image(const std::string& path, OIIO::ImageSpec spec, const float* data,
                                          const char* compression = "zip") {
  return stage_image_with(path, std::move(spec), compression,
                          [&](OIIO::ImageOutput& o) { return o.write_image(TypeDesc::FLOAT, data); });
}

void write_image_file(const std::string& path, const OIIO::ImageSpec& spec, const float* data) {
  stage_image(path, spec, data)->commit();
}


}  // namespace

void require_exr_output(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".exr")
    throw InputError(fmt::format("'{}': unsupported output extension '{}' (accepted: .exr, OpenEXR)", path,
                                 fs::path(path).extension().string()));
}

void write_frame(const AovFrame& frame, const std::string& path, const FrameWriteOptions& options) {
  require_exr_output(path);
  const int w = frame.width(), h = frame.height();
  std::vector<std::string> names;
  std::vector<const Image*> sources;
  std::vector<int> source_channel;
  std::vector<std::pair<std::string, const Image*>> chosen;
  if (options.layers.empty())
    for (const auto& [name, img] : frame.layers()) chosen.emplace_back(name, &img);
  else
    for (const auto& name : options.layers) chosen.emplace_back(name, &frame.layer(name));
  for (const auto& [name, image] : chosen) {
    const Image& img = *image;
    if (img.width() != w || img.height() != h)
      throw WorkError(fmt::format("'{}': layer '{}' is {}x{}, frame is {}x{}", path, name, img.width(),
                                  img.height(), w, h));
    auto cn = channel_names(name, img.channels());
    for (int c = 0; c < img.channels(); ++c) {
      names.push_back(cn[c]);
      sources.push_back(&img);
      source_channel.push_back(c);
    }
  }
  if (names.empty()) throw WorkError(fmt::format("'{}': frame has no layers to write", path));
  const int nch = int(names.size());
  // Interleaved a strip of rows at a time, each strip handed to the writer before the next: a
  // whole interleaved copy of a 1920x1080 frame (109 channels) was another 0.9 GB at the peak.
  // Row by row within a strip (a row of the output stays in cache while every channel is copied
  // into it); not value-initialised, every element is written.
  const int strip_rows = int(std::clamp<std::int64_t>((std::int64_t(1) << 24) / (std::int64_t(w) * nch), 16, 64));
  std::unique_ptr<float[]> strip(new float[std::size_t(w) * std::min(strip_rows, h) * nch]);
  auto interleave = [&](int y0, int y1) {
    tbb::parallel_for(y0, y1, [&](int y) {
      float* row = strip.get() + std::size_t(y - y0) * w * nch;
      for (int c = 0; c < nch; ++c) {
        const Image& img = *sources[c];
        const int sc = source_channel[c], ic = img.channels();
        const float* src = img.data() + std::size_t(y) * w * ic + sc;
        for (int x = 0; x < w; ++x) row[std::size_t(x) * nch + c] = src[std::size_t(x) * ic];
      }
    });
  };
  auto write_strips = [&](OIIO::ImageOutput& o) {
    for (int y0 = 0; y0 < h; y0 += strip_rows) {
      const int y1 = std::min(h, y0 + strip_rows);
      interleave(y0, y1);
      if (!o.write_scanlines(y0, y1, 0, TypeDesc::FLOAT, strip.get())) return false;
    }
    return true;
  };
  OIIO::ImageSpec spec(w, h, nch, TypeDesc::FLOAT);
  spec.channelnames = names;
  const bool with_edges = frame.edges && options.edges;
  if (!options.durable) {
    if (with_edges) throw WorkError(fmt::format("'{}': a frame with an edge file is always written durably", path));
    put_meta(spec, frame.meta, w, h, 0);
    spec.attribute("compression", options.compress ? "zip" : "none");
    auto o = OIIO::ImageOutput::create(path);
    if (!o || !o->open(path, spec) || !write_strips(*o) || !o->close())
      throw WorkError(fmt::format("'{}': write failed: {}", path, o ? o->geterror() : OIIO::geterror()));
    return;
  }
  put_meta(spec, frame.meta, w, h, with_edges ? frame.edges->size() : 0);
  // Both files are written in full (and checked) before either is committed; the edge file is
  // committed first, so a frame on disk that names an edge file always has it complete, and the
  // frame records the edge file's SHA-256 so that a stale one is never paired with it.
  std::unique_ptr<AtomicOutput> edges;
  if (with_edges) {
    std::string digest;
    edges = exr::stage_edges(*frame.edges, w, h, edges_path(path), digest);
    spec.attribute(std::string(kAttrPrefix) + "edges_sha256", digest);
  }
  auto image = stage_image_with(path, spec, options.compress ? "zip" : "none", write_strips);
  if (edges) edges->commit();
  image->commit();
}


AovFrame read_frame(const std::string& path, const std::vector<std::string>& required,
                    const std::optional<std::vector<std::string>>& only) {
  auto in = open_input(path);
  const OIIO::ImageSpec spec = in->spec();
  if (spec.deep) throw InputError(fmt::format("'{}': is a deep image, expected a flat AOV frame", path));
  Image::check_size(spec.width, spec.height, spec.nchannels, path.c_str());
  const int w = spec.width, h = spec.height, nch = spec.nchannels;

  AovFrame frame(w, h);
  std::size_t edge_pixels = 0;
  try {
    frame.meta = get_meta(spec, &edge_pixels);
  } catch (const InputError& e) {
    throw InputError(fmt::format("'{}': {}", path, e.what()));
  }
  // The layers to keep, each with the file's channel index of its channels.
  std::map<std::string, std::vector<std::string>> groups;
  for (const auto& ch : spec.channelnames) groups[layer_of(ch)].push_back(ch);
  struct Wanted {
    std::string name;
    std::vector<int> idx;
  };
  std::vector<Wanted> wanted;
  int kept_channels = 0;
  for (const auto& [name, chans] : groups) {
    if (only && std::find(only->begin(), only->end(), name) == only->end()) continue;
    const auto expected = channel_names(name, int(chans.size()));
    std::vector<int> idx;
    for (const auto& e : expected) idx.push_back(spec.channelindex(e));
    // Not a layer we know (e.g. an alpha channel): skipped, unless it was asked for (below).
    if (std::find(idx.begin(), idx.end(), -1) != idx.end()) continue;
    kept_channels += int(idx.size());
    wanted.push_back({name, std::move(idx)});
  }
  // Rows per read: up to 4 of OpenEXR's 16-row zip chunks, fewer for very wide files of many
  // channels (the strip stays under 64 MB). A tiled file (another renderer's; OpenImageIO's
  // read_scanlines divides by zero on one) is read in strips of whole tile rows.
  const bool tiled = spec.tile_width > 0 && spec.tile_height > 0;
  int strip_rows = int(std::clamp<std::int64_t>((std::int64_t(1) << 24) / (std::int64_t(w) * nch), 1, 64));
  if (tiled) strip_rows = int(std::min<std::int64_t>(h, std::int64_t(std::max(1, strip_rows / spec.tile_height)) * spec.tile_height));
  strip_rows = std::min(strip_rows, h);
  // The kept layers, and one strip of the file's interleaved rows at a time: a whole interleaved
  // copy of a 1920x1080 frame (109 channels) was another 0.9 GB at the peak. The budget counts
  // the strip too (a file of tall tiles may need the whole image in one).
  refuse_decode_beyond(path, w, h, nch,
                       (double(w) * h * kept_channels + double(w) * strip_rows * nch) * sizeof(float),
                       memory_budget_bytes());
  std::vector<Image> images;
  images.reserve(wanted.size());
  for (const auto& l : wanted) images.emplace_back(w, h, int(l.idx.size()));
  if (!wanted.empty()) {
    std::vector<float> strip(std::size_t(w) * strip_rows * nch);
    for (int y0 = 0; y0 < h; y0 += strip_rows) {
      const int y1 = std::min(h, y0 + strip_rows);
      const bool read = tiled ? in->read_tiles(0, 0, spec.x, spec.x + w, y0 + spec.y, y1 + spec.y, spec.z, spec.z + 1, 0, nch,
                                               TypeDesc::FLOAT, strip.data())
                              : in->read_scanlines(0, 0, y0 + spec.y, y1 + spec.y, 0, 0, nch, TypeDesc::FLOAT, strip.data());
      if (!read)
        throw InputError(fmt::format("'{}': cannot read pixels: {}", path, in->geterror()));
      tbb::parallel_for(std::size_t(0), wanted.size(), [&](std::size_t k) {
        const std::vector<int>& idx = wanted[k].idx;
        const int n = int(idx.size());
        float* dst = images[k].data() + std::size_t(y0) * w * n;
        const std::size_t pixels = std::size_t(y1 - y0) * w;
        for (std::size_t i = 0; i < pixels; ++i)
          for (int c = 0; c < n; ++c) dst[i * n + c] = strip[i * nch + idx[c]];
      });
    }
  }
  in->close();
  for (std::size_t k = 0; k < wanted.size(); ++k) frame.set(wanted[k].name, std::move(images[k]));
  for (const auto& r : required) {
    if (!frame.has(r)) {
      auto want = channel_names(r, default_channels(r));
      std::vector<std::string> missing;
      for (auto& c : want)
        if (spec.channelindex(c) < 0) missing.push_back(c);
      if (missing.empty()) missing = want;
      throw InputError(fmt::format("'{}': missing channel{} {} (layer '{}' is required)", path,
                                   missing.size() > 1 ? "s" : "", fmt::join(missing, ", "), r));
    }
  }
  if (edge_pixels > 0) {
    const std::string ep = edges_path(path);
    if (!fs::exists(ep))
      throw InputError(fmt::format("'{}': header lists {} edge pixels but the edge file '{}' is missing",
                                   path, edge_pixels, ep));
    if (const std::string want = attr_string(spec, "edges_sha256"); !want.empty() && sha256_file(ep) != want)
      throw InputError(fmt::format("'{}': the edge file '{}' is not the one written with this frame (its SHA-256 "
                                   "differs from the frame's record): render the frame again",
                                   path, ep));
    frame.edges = exr::read_edges(ep, w, h);
    if (frame.edges->size() != edge_pixels)
      throw InputError(fmt::format("'{}': holds {} edge pixels, '{}' lists {}", ep, frame.edges->size(),
                                   path, edge_pixels));
  }
  return frame;
}

void write_rgb(const Image& rgb, const std::string& path,
               const std::vector<std::pair<std::string, std::string>>& attributes) {
  require_exr_output(path);
  if (rgb.channels() != 3)
    throw WorkError(fmt::format("'{}': expected a 3-channel image, got {}", path, rgb.channels()));
  OIIO::ImageSpec spec(rgb.width(), rgb.height(), 3, TypeDesc::FLOAT);
  spec.channelnames = {"R", "G", "B"};
  for (auto& [k, v] : attributes) spec.attribute(std::string(kAttrPrefix) + k, v);
  write_image_file(path, spec, rgb.data());
}

std::map<std::string, std::string> read_rgb_attributes(const std::string& path) {
  const std::string prefix = kAttrPrefix;
  std::map<std::string, std::string> out;
  for (const auto& [name, value] : read_exr_channels(path, /*with_pixels=*/false).attributes)
    if (name.rfind(prefix, 0) == 0) out.emplace(name.substr(prefix.size()), value);
  return out;
}

Image read_rgb(const std::string& path) {
  auto in = open_input(path);
  const OIIO::ImageSpec spec = in->spec();
  if (spec.deep) throw InputError(fmt::format("'{}': is a deep image, expected a flat RGB image", path));
  Image::check_size(spec.width, spec.height, spec.nchannels, path.c_str());
  check_decode_memory(path, spec.width, spec.height, 3, memory_budget_bytes());
  int idx[3];
  const char* want[3] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c) {
    idx[c] = spec.channelindex(want[c]);
    if (idx[c] < 0)
      throw InputError(fmt::format("'{}': missing channel '{}' (expected R, G, B; the file has {})", path,
                                   want[c], fmt::join(spec.channelnames, ", ")));
  }
  // Only the channel range that holds R, G, B is read; straight into the image when it is exactly
  // R, G, B in that order (a plug-in's output, every image the harness writes).
  const int first = std::min({idx[0], idx[1], idx[2]}), last = std::max({idx[0], idx[1], idx[2]});
  const int nch = last - first + 1;
  Image out(spec.width, spec.height, 3);
  if (nch == 3 && idx[0] == first && idx[1] == first + 1) {
    if (!in->read_image(0, 0, first, last + 1, TypeDesc::FLOAT, out.data()))
      throw InputError(fmt::format("'{}': cannot read pixels: {}", path, in->geterror()));
    return out;
  }
  std::vector<float> buf(std::size_t(spec.width) * spec.height * nch);
  if (!in->read_image(0, 0, first, last + 1, TypeDesc::FLOAT, buf.data()))
    throw InputError(fmt::format("'{}': cannot read pixels: {}", path, in->geterror()));
  for (std::size_t i = 0; i < out.pixel_count(); ++i)
    for (int c = 0; c < 3; ++c) out.data()[i * 3 + c] = buf[i * nch + idx[c] - first];
  return out;
}

int ExrChannels::index(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return int(i);
  return -1;
}

const std::vector<float>& ExrChannels::plane(const std::string& name) const {
  const int i = index(name);
  if (i < 0) throw InputError(fmt::format("no channel '{}'", name));
  return planes[std::size_t(i)];
}

ExrChannels read_exr_channels(const std::string& path, bool with_pixels) {
  auto in = open_input(path);
  ExrChannels out;
  for (int part = 0; in->seek_subimage(part, 0); ++part) {
    const OIIO::ImageSpec spec = in->spec();
    if (spec.deep) throw InputError(fmt::format("'{}': part {} is a deep image, expected flat channels", path, part));
    Image::check_size(spec.width, spec.height, spec.nchannels, path.c_str());
    if (with_pixels) check_decode_memory(path, spec.width, spec.height, spec.nchannels, memory_budget_bytes());
    if (part == 0) {
      out.width = spec.width;
      out.height = spec.height;
    } else if (spec.width != out.width || spec.height != out.height) {
      throw InputError(fmt::format("'{}': part {} is {}x{}, part 0 is {}x{} (parts of one frame must share a size)",
                                   path, part, spec.width, spec.height, out.width, out.height));
    }
    for (const auto& a : spec.extra_attribs) out.attributes.emplace(a.name().string(), a.get_string());
    for (const auto& name : spec.channelnames) {
      if (out.has(name)) throw InputError(fmt::format("'{}': channel '{}' appears in two parts", path, name));
      out.names.push_back(name);
    }
    if (!with_pixels) continue;
    const std::size_t n = std::size_t(spec.width) * spec.height;
    std::vector<float> buf(n * std::size_t(spec.nchannels));
    if (!in->read_image(part, 0, 0, spec.nchannels, TypeDesc::FLOAT, buf.data()))
      throw InputError(fmt::format("'{}': cannot read the pixels of part {}: {}", path, part, in->geterror()));
    for (int c = 0; c < spec.nchannels; ++c) {
      std::vector<float> plane(n);
      for (std::size_t i = 0; i < n; ++i) plane[i] = buf[i * std::size_t(spec.nchannels) + std::size_t(c)];
      out.planes.push_back(std::move(plane));
    }
  }
  return out;
}

}  // namespace dnb
