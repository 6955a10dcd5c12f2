//! Prints, for each Rust source file named on the command line, every module path its code names
//! that starts at `crate`, `super` or `self`: one line `FILE<TAB>PATH` each, use trees expanded;
//! and every integer literal its code writes in hex, as written: one line `FILE<TAB>=LITERAL`
//! each (an object index such as 0x6060 shows where a layer names a device's objects).
//!
//! Code, not text: the file is parsed by syn, so string literals, raw strings, char literals and
//! comments (doc comments included) name nothing. Attributes name nothing either (a doc link may
//! point anywhere), and items under `#[cfg(test)]` are passed over, because tests may use
//! anything. Macro invocations are token streams syn does not parse; a path written in one counts
//! where its tokens read `crate :: a :: b`.
//!
//! Exits 1 naming the file when one does not parse.

use std::process::ExitCode;

use proc_macro2::{TokenStream, TokenTree};
use syn::visit::{self, Visit};

const ROOTS: [&str; 3] = ["crate", "super", "self"];

#[derive(Default)]
struct Paths(Vec<String>);

/// Whether a literal is an integer written in hex.
fn is_hex(literal: &str) -> bool {
    literal.starts_with("0x") || literal.starts_with("0X")
}

impl Paths {
    fn push(&mut self, segments: &[String]) {
        if segments.len() > 1 && ROOTS.contains(&segments[0].as_str()) {
            self.0.push(segments.join("::"));
        }
    }

    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &syn::UseTree) {
        match tree {
            syn::UseTree::Path(p) => {
                prefix.push(p.ident.to_string());
                self.use_tree(prefix, &p.tree);
                prefix.pop();
            }
            syn::UseTree::Name(n) => self.leaf(prefix, n.ident.to_string()),
            syn::UseTree::Rename(r) => self.leaf(prefix, r.ident.to_string()),
            syn::UseTree::Glob(_) => self.push(prefix),
            syn::UseTree::Group(g) => g.items.iter().for_each(|t| self.use_tree(prefix, t)),
        }
    }

    fn leaf(&mut self, prefix: &mut Vec<String>, name: String) {
        // `use a::b::{self}` names a::b.
        if name != "self" || prefix.is_empty() {
            prefix.push(name);
            self.push(prefix);
            prefix.pop();
        } else {
            self.push(prefix);
        }
    }

    /// Paths in a macro's tokens: an identifier of ROOTS followed by `::`-joined identifiers.
    fn tokens(&mut self, tokens: TokenStream) {
        let trees: Vec<TokenTree> = tokens.into_iter().collect();
        let mut i = 0;
        while i < trees.len() {
            match &trees[i] {
                TokenTree::Group(g) => self.tokens(g.stream()),
                TokenTree::Literal(l) if is_hex(&l.to_string()) => self.0.push(format!("={l}")),
                TokenTree::Ident(id) if ROOTS.contains(&id.to_string().as_str()) => {
                    let mut segments = vec![id.to_string()];
                    let mut j = i + 1;
                    while let (
                        Some(TokenTree::Punct(a)),
                        Some(TokenTree::Punct(b)),
                        Some(TokenTree::Ident(next)),
                    ) = (trees.get(j), trees.get(j + 1), trees.get(j + 2))
                    {
                        if a.as_char() != ':' || b.as_char() != ':' {
                            break;
                        }
                        segments.push(next.to_string());
                        j += 3;
                    }
                    self.push(&segments);
                    i = j - 1;
                }
                _ => {}
            }
            i += 1;
        }
    }
}

fn is_cfg_test(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        a.path().is_ident("cfg") && a.parse_args::<syn::Ident>().is_ok_and(|id| id == "test")
    })
}

impl<'ast> Visit<'ast> for Paths {
    fn visit_attribute(&mut self, _: &'ast syn::Attribute) {}

    fn visit_item(&mut self, item: &'ast syn::Item) {
        let attrs = match item {
            syn::Item::Const(i) => &i.attrs,
            syn::Item::Enum(i) => &i.attrs,
            syn::Item::Fn(i) => &i.attrs,
            syn::Item::Impl(i) => &i.attrs,
            syn::Item::Macro(i) => &i.attrs,
            syn::Item::Mod(i) => &i.attrs,
            syn::Item::Static(i) => &i.attrs,
            syn::Item::Struct(i) => &i.attrs,
            syn::Item::Trait(i) => &i.attrs,
            syn::Item::Type(i) => &i.attrs,
            syn::Item::Use(i) => &i.attrs,
            _ => return visit::visit_item(self, item),
        };
        if !is_cfg_test(attrs) {
            visit::visit_item(self, item);
        }
    }

    fn visit_impl_item(&mut self, item: &'ast syn::ImplItem) {
        let attrs = match item {
            syn::ImplItem::Const(i) => &i.attrs,
            syn::ImplItem::Fn(i) => &i.attrs,
            syn::ImplItem::Type(i) => &i.attrs,
            syn::ImplItem::Macro(i) => &i.attrs,
            _ => return visit::visit_impl_item(self, item),
        };
        if !is_cfg_test(attrs) {
            visit::visit_impl_item(self, item);
        }
    }

    fn visit_item_use(&mut self, item: &'ast syn::ItemUse) {
        self.use_tree(&mut Vec::new(), &item.tree);
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        let segments: Vec<String> = path.segments.iter().map(|s| s.ident.to_string()).collect();
        self.push(&segments);
        visit::visit_path(self, path);
    }

    fn visit_lit_int(&mut self, literal: &'ast syn::LitInt) {
        if is_hex(&literal.to_string()) {
            self.0.push(format!("={literal}"));
        }
    }

    fn visit_macro(&mut self, mac: &'ast syn::Macro) {
        self.visit_path(&mac.path);
        self.tokens(mac.tokens.clone());
    }
}

fn main() -> ExitCode {
    let mut failed = false;
    for file in std::env::args().skip(1) {
        let parsed = std::fs::read_to_string(&file)
            .map_err(|e| e.to_string())
            .and_then(|text| syn::parse_file(&text).map_err(|e| e.to_string()));
        match parsed {
            Ok(ast) => {
                let mut paths = Paths::default();
                paths.visit_file(&ast);
                for path in paths.0 {
                    println!("{file}\t{path}");
                }
            }
            Err(e) => {
                eprintln!("module-deps: {file} does not parse: {e}");
                failed = true;
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
