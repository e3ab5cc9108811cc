// Checkpoint files: layout in relit/io/checkpoint.hpp.
#include <relit/config.hpp>
#include <relit/error.hpp>
#include <relit/io/checkpoint.hpp>
#include <relit/io/file.hpp>
#include <relit/version.hpp>

#include <cstring>

namespace relit::io {

namespace {

constexpr char kMagic[8] = {'R', 'E', 'L', 'I', 'T', 'C', 'K', 'P'};

std::uint64_t fnv1a(const char* data, std::size_t n) {
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(data[i]);
    h *= 1099511628211ull;
  }
  return h;
}

// Little-endian integer I/O (relit targets little-endian hosts; floats are stored as the host has them
// and checked below).
template <class T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  for (std::size_t i = 0; i < sizeof(T); ++i)
    b[i] = static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff);
  out.append(b, sizeof(T));
}
template <class T>
T get(const std::string& in, std::size_t at) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) v |= std::uint64_t(static_cast<unsigned char>(in[at + i])) << (8 * i);
  return static_cast<T>(v);
}

bool little_endian() {
  const std::uint32_t one = 1;
  char c;
  std::memcpy(&c, &one, 1);
  return c == 1;
}

}  // namespace

void save_checkpoint(const std::string& path, const Checkpoint& checkpoint) {
  if (!little_endian()) throw IOError("checkpoints are little-endian; this host is not");
  Json header = checkpoint.header.is_object() ? checkpoint.header : Json::object();
  header["format_version"] = kCheckpointVersion;
  header["library_version"] = relit::version();
  header["tensors"] = Json::array();
  std::uint64_t offset = 0;
  for (const auto& [name, values] : checkpoint.tensors) {
    header["tensors"].push_back({{"name", name}, {"count", values.size()}, {"offset", offset}});
    offset += values.size() * sizeof(float);
  }
  const std::string text = header.dump();
  std::string out(kMagic, sizeof kMagic);
  put<std::uint32_t>(out, kCheckpointVersion);
  put<std::uint64_t>(out, text.size());
  out += text;
  out.reserve(out.size() + offset + 8);
  for (const auto& [name, values] : checkpoint.tensors)
    out.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
  put<std::uint64_t>(out, fnv1a(out.data(), out.size()));
  write_file_atomic(path, out);
}

Checkpoint load_checkpoint(const std::string& path) {
  const std::string data = read_file(path);
  auto bad = [&](const std::string& why) { return IOError("checkpoint " + path + " is not usable: " + why); };
  if (data.size() < sizeof kMagic + 4 + 8 + 8 || std::memcmp(data.data(), kMagic, sizeof kMagic) != 0)
    throw bad("it is not a relit checkpoint (bad magic or too short)");
  const auto version = get<std::uint32_t>(data, 8);
  if (version != kCheckpointVersion)
    throw bad("format version " + std::to_string(version) + ", this relit reads version " +
              std::to_string(kCheckpointVersion));
  const std::size_t body = data.size() - 8;
  if (get<std::uint64_t>(data, body) != fnv1a(data.data(), body))
    throw bad("checksum mismatch: the file is truncated or corrupt");
  const auto header_size = get<std::uint64_t>(data, 12);
  const std::size_t start = 20;
  if (header_size > body - start) throw bad("header length exceeds the file");
  Checkpoint ck;
  try {
    ck.header = parse_json(data.substr(start, header_size), "its header");
  } catch (const ConfigError& e) {
    throw bad(e.what());
  }
  const std::size_t blobs = start + header_size;
  if (!ck.header.contains("tensors") || !ck.header["tensors"].is_array()) throw bad("header has no tensor table");
  for (const auto& t : ck.header["tensors"]) {
    // A forged header may hold anything: check each entry's types before use, and compare sizes without
    // multiplying (a count of 2^62 floats would overflow).
    const auto field = [&](const char* key) { return t.is_object() && t.contains(key) ? &t.at(key) : nullptr; };
    const Json *jname = field("name"), *jcount = field("count"), *joffset = field("offset");
    if (!jname || !jname->is_string() || !jcount || !jcount->is_number_unsigned() || !joffset ||
        !joffset->is_number_unsigned())
      throw bad("the tensor table entry " + t.dump().substr(0, 200) +
                " lacks a string 'name' and non-negative integer 'count' and 'offset'");
    const std::string name = jname->get<std::string>();
    const std::uint64_t count = jcount->get<std::uint64_t>(), offset = joffset->get<std::uint64_t>();
    if (name.empty() || offset > body - blobs || count > (body - blobs - offset) / sizeof(float))
      throw bad("tensor '" + name + "' lies outside the file");
    if (ck.tensors.count(name)) throw bad("tensor '" + name + "' appears twice in the header");
    std::vector<float> values(count);
    if (count) std::memcpy(values.data(), data.data() + blobs + offset, count * sizeof(float));  // (null for 0)
    ck.tensors.emplace(name, std::move(values));
  }
  return ck;
}

}  // namespace relit::io
