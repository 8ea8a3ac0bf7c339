// Compares two HDF5 result files object by object: every dataset's and attribute's bytes, except the
// attributes named in `skip` (wall-clock timings). Used by the MPI tests: the same bits whatever the number
// of processes.
#pragma once
#include <hdf5.h>

#include <map>
#include <set>
#include <string>
#include <vector>

#include "hinf/h5.hpp"

namespace hinf::test {

namespace detail {

inline std::string read_raw(hid_t obj, bool attribute) {
    h5::Handle type(attribute ? H5Aget_type(obj) : H5Dget_type(obj));
    h5::Handle space(attribute ? H5Aget_space(obj) : H5Dget_space(obj));
    const hssize_t count = H5Sget_simple_extent_npoints(space.get());
    if (H5Tget_class(type.get()) == H5T_STRING && H5Tis_variable_str(type.get()) > 0) {
        std::vector<char*> s(std::size_t(count), nullptr);
        h5::Handle mem(H5Tcopy(H5T_C_S1));
        H5Tset_size(mem.get(), H5T_VARIABLE);
        if (attribute) H5Aread(obj, mem.get(), s.data());
        else H5Dread(obj, mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, s.data());
        std::string out;
        for (char* c : s) out += std::string(c ? c : "") + '\0';
        H5Dvlen_reclaim(mem.get(), space.get(), H5P_DEFAULT, s.data());
        return out;
    }
    std::string buf(std::size_t(count) * H5Tget_size(type.get()), '\0');
    if (attribute) H5Aread(obj, type.get(), buf.data());
    else H5Dread(obj, type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
    return buf;
}

struct Walk {
    hid_t file;
    std::set<std::string> skip;
    std::map<std::string, std::string> items;  // "path" or "path@attr" -> bytes
};

inline herr_t visit_attr(hid_t loc, const char* name, const H5A_info_t*, void* op) {
    auto* w = static_cast<std::pair<Walk*, std::string>*>(op);
    if (w->first->skip.count(name)) return 0;
    h5::Handle a(H5Aopen(loc, name, H5P_DEFAULT));
    w->first->items[w->second + "@" + name] = read_raw(a.get(), true);
    return 0;
}

inline herr_t visit_object(hid_t root, const char* name, const H5O_info_t* info, void* op) {
    Walk* w = static_cast<Walk*>(op);
    h5::Handle obj(H5Oopen(root, name, H5P_DEFAULT));
    std::pair<Walk*, std::string> ctx{w, name};
    H5Aiterate2(obj.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, visit_attr, &ctx);
    if (info->type == H5O_TYPE_DATASET) w->items[name] = read_raw(obj.get(), false);
    return 0;
}

}  // namespace detail

/// Every dataset and attribute of an HDF5 file as bytes, by path (attributes as "path@name").
inline std::map<std::string, std::string> h5_contents(const std::string& path, const std::set<std::string>& skip) {
    h5::Handle f = h5::open_file(path, false);
    detail::Walk w{f.get(), skip, {}};
    H5Ovisit(f.get(), H5_INDEX_NAME, H5_ITER_INC, detail::visit_object, &w);
    return w.items;
}

/// The paths where two files differ (a missing item counts), empty when they hold the same bits.
inline std::vector<std::string> h5_differences(const std::string& a, const std::string& b,
                                               const std::set<std::string>& skip) {
    const auto ca = h5_contents(a, skip), cb = h5_contents(b, skip);
    std::vector<std::string> diff;
    for (const auto& [k, v] : ca) {
        auto it = cb.find(k);
        if (it == cb.end() || it->second != v) diff.push_back(k);
    }
    for (const auto& [k, v] : cb)
        if (!ca.count(k)) diff.push_back(k);
    return diff;
}

}  // namespace hinf::test
