//! Where a URDF's mesh files are, found as ROS tools find them:
//!
//! - `package://PKG/rel/path`: `PKG` is the nearest directory above the URDF (the URDF's own
//!   included) whose `package.xml` names it (or, as rospack accepts, that is named `PKG` and
//!   has a `package.xml`), or such a directory `PKG` beside one of them (a sibling package of
//!   the same workspace); else a package found under the search roots: the caller's
//!   (`--package-path`), then `ROS_PACKAGE_PATH`'s, each crawled as rospack crawls (a root may
//!   be a package itself; the crawl does not descend into a package, nor into hidden
//!   directories or ones marked `CATKIN_IGNORE`/`COLCON_IGNORE`/`AMENT_IGNORE`).
//! - `file:///abs/path` (percent-escapes decoded), an absolute path, or a path relative to the
//!   URDF's directory.
//!
//! The crawl is bounded (depth and directory count) so that a root such as `/` ends quickly.

use quick_xml::events::Event;
use quick_xml::Reader;
use std::collections::{HashMap, HashSet, VecDeque};
use std::path::{Path, PathBuf};

/// The environment variable ROS 1 tools read package roots from (colon-separated).
pub const ROS_PACKAGE_PATH: &str = "ROS_PACKAGE_PATH";

/// Deepest directory below a search root that the package crawl looks into.
const MAX_CRAWL_DEPTH: usize = 8;
/// Most directories the crawl of one search root reads.
const MAX_CRAWL_DIRECTORIES: usize = 20_000;
/// Largest `package.xml` read (real ones have a few kB).
const MAX_PACKAGE_XML_BYTES: u64 = 1 << 20;
/// Files that tell ROS build tools to skip a directory.
const IGNORE_MARKERS: &[&str] = &["CATKIN_IGNORE", "COLCON_IGNORE", "AMENT_IGNORE"];

/// The package search roots: `explicit` (the caller's, searched first), then the entries of
/// `ROS_PACKAGE_PATH`.
pub fn package_search_roots(explicit: &[PathBuf]) -> Vec<PathBuf> {
    let mut roots = explicit.to_vec();
    if let Some(value) = std::env::var_os(ROS_PACKAGE_PATH) {
        roots.extend(std::env::split_paths(&value).filter(|p| !p.as_os_str().is_empty()));
    }
    roots
}

/// Resolves the mesh file names of one URDF; remembers the packages it has found.
pub(crate) struct MeshFiles {
    /// The URDF's directory, absolute where it can be made so (the walk up needs its ancestors).
    urdf_dir: PathBuf,
    roots: Vec<PathBuf>,
    packages: HashMap<String, Result<PathBuf, String>>,
}

impl MeshFiles {
    pub(crate) fn new(urdf_path: &Path, roots: Vec<PathBuf>) -> Self {
        let dir = match urdf_path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let urdf_dir = std::fs::canonicalize(&dir)
            .or_else(|_| std::path::absolute(&dir))
            .unwrap_or(dir);
        MeshFiles {
            urdf_dir,
            roots,
            packages: HashMap::new(),
        }
    }

    /// `relative` under the URDF's folder or a folder above it, or under a search root.
    fn under_ancestors(&self, relative: &str) -> Option<PathBuf> {
        let relative = Path::new(relative);
        if relative.is_absolute()
            || relative
                .components()
                .any(|c| c == std::path::Component::ParentDir)
        {
            return None;
        }
        self.urdf_dir
            .ancestors()
            .chain(self.roots.iter().map(PathBuf::as_path))
            .map(|dir| dir.join(relative))
            .find(|p| p.is_file())
    }

    /// The file a URDF `<mesh filename="…">` names, if it exists; else what was looked for and
    /// where.
    pub(crate) fn resolve(&mut self, filename: &str) -> Result<PathBuf, String> {
        let name = filename.trim();
        let quoted = format!("mesh \"{name}\"");
        let path = if let Some(rest) = name.strip_prefix("package://") {
            let (package, relative) = rest.split_once('/').unwrap_or((rest, ""));
            if package.is_empty() && !relative.is_empty() {
                // `package:///path`: no package named; Pinocchio looks the path up under its
                // package directories, as here under the folders above the URDF and the roots.
                return self.under_ancestors(relative).ok_or_else(|| {
                    format!(
                        "{quoted}: names no package, and no folder above {} or on the package path holds {relative}",
                        self.urdf_dir.display()
                    )
                });
            }
            if package.is_empty() || relative.is_empty() || package == "." || package == ".." {
                return Err(format!(
                    "{quoted}: expected package://PACKAGE/path/in/the/package"
                ));
            }
            let dir = self
                .package(package)
                .map_err(|why| format!("{quoted}: {why}"))?;
            let path = dir.join(relative);
            return if path.is_file() {
                Ok(path)
            } else {
                Err(format!(
                    "{quoted}: package '{package}' is {}, but it has no file {relative} ({} not found)",
                    dir.display(),
                    path.display()
                ))
            };
        } else if let Some(rest) = name.strip_prefix("file://") {
            // file:///abs/path, or file://localhost/abs/path; other hosts are not local files.
            let rest = rest.strip_prefix("localhost").unwrap_or(rest);
            if !rest.starts_with('/') {
                return Err(format!(
                    "{quoted}: expected file:///absolute/path (a file URI names no other host)"
                ));
            }
            PathBuf::from(percent_decoded(rest).ok_or_else(|| {
                format!("{quoted}: a % not followed by two hex digits, or not UTF-8 once decoded")
            })?)
        } else if let Some((scheme, _)) = name.split_once("://") {
            return Err(format!(
                "{quoted}: the scheme {scheme}:// is not read (expected package://, file:// or a path)"
            ));
        } else if name.is_empty() {
            return Err("a <mesh> with an empty filename".into());
        } else {
            self.urdf_dir.join(name)
        };
        if path.is_file() {
            Ok(path)
        } else {
            let relative = if Path::new(name).is_relative() && !name.starts_with("file://") {
                format!(
                    ", relative to the URDF's directory {}",
                    self.urdf_dir.display()
                )
            } else {
                String::new()
            };
            Err(format!("{quoted}: no file {}{relative}", path.display()))
        }
    }

    fn package(&mut self, name: &str) -> Result<PathBuf, String> {
        if let Some(found) = self.packages.get(name) {
            return found.clone();
        }
        let found = self.find_package(name);
        self.packages.insert(name.to_string(), found.clone());
        found
    }

    fn find_package(&self, name: &str) -> Result<PathBuf, String> {
        for dir in self.urdf_dir.ancestors() {
            if is_package(dir, name) {
                return Ok(dir.to_path_buf());
            }
            let sibling = dir.join(name);
            if is_package(&sibling, name) {
                return Ok(sibling);
            }
        }
        for root in &self.roots {
            if let Some(dir) = crawl(root, name) {
                return Ok(dir);
            }
        }
        let roots = if self.roots.is_empty() {
            format!("no package path was given and {ROS_PACKAGE_PATH} is not set")
        } else {
            let list: Vec<String> = self.roots.iter().map(|r| r.display().to_string()).collect();
            format!("nor under the package path {}", list.join(":"))
        };
        Err(format!(
            "no package '{name}': no package.xml naming it in {} or a directory above it (or a subdirectory '{name}' of one), {roots}",
            self.urdf_dir.display()
        ))
    }
}

/// Whether `dir` holds the package `name`: its `package.xml` names it, or the directory is
/// called `name` and has a `package.xml`.
fn is_package(dir: &Path, name: &str) -> bool {
    let manifest = dir.join("package.xml");
    manifest.is_file()
        && (dir.file_name().is_some_and(|f| f == name)
            || package_name(&manifest).is_some_and(|n| n == name))
}

/// The `<name>` of a `package.xml`.
fn package_name(manifest: &Path) -> Option<String> {
    if std::fs::metadata(manifest).ok()?.len() > MAX_PACKAGE_XML_BYTES {
        return None;
    }
    let text = std::fs::read_to_string(manifest).ok()?;
    let mut reader = Reader::from_str(&text);
    let mut path: Vec<Vec<u8>> = Vec::new();
    loop {
        match reader.read_event().ok()? {
            Event::Start(e) => {
                path.push(e.name().as_ref().to_vec());
                if path.len() > 2 {
                    // package.xml is shallow; nothing deeper is its name.
                    path.pop();
                    reader.read_to_end(e.name()).ok()?;
                }
            }
            Event::End(_) => {
                path.pop();
            }
            Event::Text(t) if path == [b"package".to_vec(), b"name".to_vec()] => {
                let name = t.decode().ok()?.trim().to_string();
                return (!name.is_empty()).then_some(name);
            }
            Event::Eof => return None,
            _ => {}
        }
    }
}

/// The package `name` under `root` (breadth first, so the shallowest wins), if any.
fn crawl(root: &Path, name: &str) -> Option<PathBuf> {
    let mut queue = VecDeque::from([(root.to_path_buf(), 0usize)]);
    // Symbolic links may loop: each real directory is read once.
    let mut seen = HashSet::new();
    let mut read = 0usize;
    while let Some((dir, depth)) = queue.pop_front() {
        if !seen.insert(std::fs::canonicalize(&dir).unwrap_or_else(|_| dir.clone())) {
            continue;
        }
        if is_package(&dir, name) {
            return Some(dir);
        }
        // A package holds no other package (rospack does not look inside one).
        if depth >= MAX_CRAWL_DEPTH
            || (depth > 0 && dir.join("package.xml").is_file())
            || IGNORE_MARKERS.iter().any(|m| dir.join(m).exists())
        {
            continue;
        }
        read += 1;
        if read > MAX_CRAWL_DIRECTORIES {
            return None;
        }
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut children: Vec<PathBuf> = entries
            .filter_map(|e| e.ok())
            .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
            .map(|e| e.path())
            .filter(|p| p.is_dir())
            .collect();
        // The same answer on every file system, whatever order it lists entries in.
        children.sort();
        queue.extend(children.into_iter().map(|c| (c, depth + 1)));
    }
    None
}

/// `%XX` escapes of a URI path decoded; `None` for a malformed escape or non-UTF-8 result.
fn percent_decoded(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(path: &Path, text: &str) {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }

    fn manifest(name: &str) -> String {
        format!("<?xml version=\"1.0\"?>\n<package format=\"3\">\n  <name>{name}</name>\n  <version>1.0.0</version>\n</package>\n")
    }

    #[test]
    fn package_uris_are_found_above_the_urdf_by_the_name_in_package_xml() {
        let ws = tempfile::tempdir().unwrap();
        // The directory's name differs from the package's: package.xml decides.
        let pkg = ws.path().join("src/mill_description_dir");
        write(&pkg.join("package.xml"), &manifest("mill_description"));
        write(&pkg.join("meshes/base.stl"), "solid s\nendsolid s\n");
        let urdf = pkg.join("urdf/mill.urdf");
        write(&urdf, "<robot name=\"m\"/>");
        let mut files = MeshFiles::new(&urdf, Vec::new());
        let found = files
            .resolve("package://mill_description/meshes/base.stl")
            .unwrap();
        assert_eq!(
            found.canonicalize().unwrap(),
            pkg.join("meshes/base.stl").canonicalize().unwrap()
        );

        // A sibling package of the same workspace, by its directory name.
        let other = ws.path().join("src/spindle");
        write(&other.join("package.xml"), &manifest("spindle"));
        write(&other.join("meshes/motor.obj"), "v 0 0 0\n");
        assert!(files.resolve("package://spindle/meshes/motor.obj").is_ok());

        // Found package, missing file: both named.
        let e = files
            .resolve("package://mill_description/meshes/nope.stl")
            .unwrap_err();
        assert!(
            e.contains("package 'mill_description' is") && e.contains("meshes/nope.stl"),
            "{e}"
        );
    }

    #[test]
    fn package_uris_are_found_under_the_search_roots_and_missing_ones_say_where_they_were_looked_for(
    ) {
        let urdf_dir = tempfile::tempdir().unwrap();
        let urdf = urdf_dir.path().join("m.urdf");
        write(&urdf, "<robot name=\"m\"/>");
        let root = tempfile::tempdir().unwrap();
        let pkg = root.path().join("vendor/acme/acme_meshes");
        write(&pkg.join("package.xml"), &manifest("acme_meshes"));
        write(&pkg.join("x.dae"), "<COLLADA/>");
        // A package inside another package is not one rospack would find.
        write(&root.path().join("outer/package.xml"), &manifest("outer"));
        write(
            &root.path().join("outer/inner/package.xml"),
            &manifest("inner"),
        );
        let mut files = MeshFiles::new(&urdf, vec![root.path().to_path_buf()]);
        assert_eq!(
            files.resolve("package://acme_meshes/x.dae").unwrap(),
            pkg.join("x.dae")
        );
        let e = files.resolve("package://inner/a.stl").unwrap_err();
        assert!(e.contains("no package 'inner'"), "{e}");
        assert!(e.contains(&root.path().display().to_string()), "{e}");

        let mut without_roots = MeshFiles::new(&urdf, Vec::new());
        let e = without_roots
            .resolve("package://acme_meshes/x.dae")
            .unwrap_err();
        assert!(
            e.contains("no package path was given") && e.contains(ROS_PACKAGE_PATH),
            "{e}"
        );
    }

    #[test]
    fn relative_absolute_and_file_uris() {
        let dir = tempfile::tempdir().unwrap();
        let urdf = dir.path().join("robot/m.urdf");
        write(&urdf, "<robot name=\"m\"/>");
        let mesh = dir.path().join("robot/meshes/a b.stl");
        write(&mesh, "solid s\nendsolid s\n");
        let mut files = MeshFiles::new(&urdf, Vec::new());
        let canonical = mesh.canonicalize().unwrap();
        let same = |p: PathBuf| p.canonicalize().unwrap() == canonical;
        assert!(same(files.resolve("meshes/a b.stl").unwrap()));
        assert!(same(files.resolve(mesh.to_str().unwrap()).unwrap()));
        let uri = format!("file://{}", mesh.to_str().unwrap().replace(' ', "%20"));
        assert!(same(files.resolve(&uri).unwrap()));
        let e = files.resolve("meshes/missing.stl").unwrap_err();
        assert!(
            e.contains("missing.stl") && e.contains("relative to the URDF's directory"),
            "{e}"
        );
        let e = files.resolve("model://thing/mesh.stl").unwrap_err();
        assert!(e.contains("model://"), "{e}");
        assert!(files.resolve("file://otherhost/x.stl").is_err());
        assert!(files.resolve("file:///a%zz.stl").is_err());
        // `package:///path` names no package: the path under a folder above the URDF, as
        // Pinocchio reads it.
        let root_name = dir
            .path()
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .to_string();
        let uri = format!("package:///{root_name}/robot/meshes/a b.stl");
        let outer = MeshFiles::new(&urdf, Vec::new()).resolve(&uri);
        assert!(same(outer.unwrap()), "{uri}");
        let e = files.resolve("package:///nowhere/x.stl").unwrap_err();
        assert!(e.contains("names no package"), "{e}");
        assert!(files.resolve("package:///../robot/meshes/a b.stl").is_err());
    }
}
