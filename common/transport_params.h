#pragma once
// The typed meaning of a transport file's parameters (docs/transport-format.md): the
// one place that writes and reads the material (name, sigma_s', sigma_a, eta, g), the
// scale the mesh was given, the scattering components and the sample area, so that
// the precomputation, the renderers and the reference agree on every key and its
// format. The file stores parameters as text (common/transport_file.h); everything
// else (pass settings, timings, the input digest) is the precomputation's own record.
//
// Errors: reading a malformed value throws prt::Error(<transport file path>,
// "parameter <key> ...") on one line.

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/bssrdf.h"
#include "common/transport_file.h"

namespace prt {

using ParameterList = std::vector<std::pair<std::string, std::string>>;

// Which parts of the radiance: "ms" = dipole multiple scattering (Wang Eq. 6-8),
// "ss" = single scattering (Wang Eqs. 10-11; isotropic or K phase terms). The same
// type selects what to precompute, what a file holds and what to render.
struct ScatteringComponents {
    bool multipleScattering = true;
    bool singleScattering = false;
    // What a file holds (componentsOf): its single scattering is inside its
    // multiple-scattering vectors (prt-precompute --fold-ss), so the two can only be
    // shown together. Never set in a request; operator& drops it.
    bool folded = false;

    static constexpr ScatteringComponents all() { return {true, true}; }
    static constexpr ScatteringComponents none() { return {false, false}; }
    bool any() const { return multipleScattering || singleScattering; }
    ScatteringComponents operator&(const ScatteringComponents& o) const {
        return {multipleScattering && o.multipleScattering, singleScattering && o.singleScattering};
    }
    bool operator==(const ScatteringComponents&) const = default;
};

// The spellings every tool accepts for --components: "ms", "ss", "ms,ss", "ss,ms" and
// "all". Anything else (unknown or repeated names, empty items, spaces, upper case,
// "all" inside a list) throws prt::Error("--components", reason).
ScatteringComponents parseScatteringComponents(const std::string& text);
// "ms", "ss", "ms,ss" (or "" for none): what parseScatteringComponents reads back.
std::string toString(const ScatteringComponents& c);

// The parameter of a file whose isotropic single scattering was added into its
// multiple-scattering vectors (value "1"; precompute/job/fold_single_scattering.h).
inline constexpr const char* kFoldedSingleScatteringParameter = "ss_folded_into_ms";

// What a file holds, from its component sections (and kFoldedSingleScatteringParameter:
// both components, folded).
ScatteringComponents componentsOf(const TransportFile& file);
ScatteringComponents componentsOf(const TransportFileInfo& info);

// The components to render for a --components request: "all" = whatever the file
// has; an explicit request for a component the file lacks is an error, and so is
// selecting nothing, and one component alone of a folded file. Errors name `transportPath`.
ScatteringComponents selectComponents(const std::string& request, const ScatteringComponents& available,
                                      const std::string& transportPath);

// Numbers as stored: %.9g (a double survives the round trip to float precision).
std::string formatParameter(double v);
std::string formatParameter(const glm::dvec3& v);  // "r,g,b"

// The parameters of a material, in the file's order: material, sigma_s_prime,
// sigma_a, eta, g.
ParameterList materialParameters(const Material& m);

// The typed parameters a transport file carries (all optional: test scenes and
// third-party writers may store only some).
struct TransportParameters {
    std::optional<Material> material;      // when sigma_s_prime, sigma_a and eta are all present
    std::optional<double> eta;              // "eta" (also material->eta)
    std::optional<ScatteringComponents> components;  // "components"
    std::optional<double> sampleAreaMm2;    // "sample_area_mm2": A_i of the precompute's samples
    std::optional<uint64_t> samples;        // "samples": their count
    std::optional<uint64_t> seed;           // "seed": the precompute's sample seed
};

// Reads and validates the parameters above (eta in [kMinEta, kMaxEta], a material that
// passes validateMaterial). `path` names the file in errors.
TransportParameters readTransportParameters(const ParameterList& parameters, const std::string& path);

}  // namespace prt
