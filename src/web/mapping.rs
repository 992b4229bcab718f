//! The column-mapping dialog and the mappings remembered in `localStorage`.
//!
//! When a dropped file's header names no column this tool knows, the page shows the
//! columns with their first values and asks what each one is (the choices are the
//! core's `MAPPING_TARGETS`). The answer is remembered under the file's header, so the
//! next file with the same columns is read without asking (see [`super::storage`] for
//! what happens to an entry that cannot be read).

use std::collections::BTreeMap;
use std::rc::Rc;

use gloo::events::EventListener;
use wasm_bindgen::JsCast;
use web_sys::{HtmlDialogElement, HtmlSelectElement};

use super::page::Page;
use super::storage;
use crate::io::delimited::{suggested_target, ColumnMapping, Preview, MAPPING_TARGETS};

const DIALOG_ID: &str = "mapping-dialog";

/// Header signature → mapping.
type Remembered = BTreeMap<String, ColumnMapping>;

fn load() -> Remembered {
    storage::load(storage::MAPPINGS_KEY, "column mappings").unwrap_or_default()
}

fn save(remembered: &Remembered) {
    storage::save(storage::MAPPINGS_KEY, remembered);
}

/// Whether the user saved any mapping (if not, no file's header needs reading first).
pub fn any_remembered() -> bool {
    !load().is_empty()
}

/// The mapping remembered for a header, if any.
pub fn remembered(signature: &str) -> Option<ColumnMapping> {
    load().remove(signature)
}

/// Shows the dialog for `file`; "Read the file" re-reads it with the chosen mapping
/// (and remembers it), "Cancel" leaves the error shown.
pub fn open_dialog(
    page: &Rc<Page>,
    file: web_sys::File,
    preview: &Preview,
    reason: &str,
    signature: Option<String>,
) {
    let document = &page.document;
    let Some(dialog) = document
        .get_element_by_id(DIALOG_ID)
        .and_then(|element| element.dyn_into::<HtmlDialogElement>().ok())
    else {
        return;
    };
    if let Some(reason_element) = document.get_element_by_id("mapping-reason") {
        reason_element.set_text_content(Some(&super::wording::for_page(reason)));
    }
    let Some(rows) = document.get_element_by_id("mapping-rows") else {
        return;
    };
    rows.set_text_content(None);
    for (column_idx, (column, first_value)) in preview
        .columns
        .iter()
        .zip(&preview.first_values)
        .enumerate()
    {
        let Ok(row) = document.create_element("tr") else {
            continue;
        };
        for text in [column.as_str(), first_value.as_str()] {
            if let Ok(cell) = document.create_element("td") {
                cell.set_text_content(Some(text));
                let _ = row.append_child(&cell);
            }
        }
        let Ok(cell) = document.create_element("td") else {
            continue;
        };
        let Ok(select) = document.create_element("select") else {
            continue;
        };
        select.set_id(&format!("mapping-{column_idx}"));
        let _ = select.set_attribute("aria-label", &format!("read column {column} as"));
        let suggested = suggested_target(column);
        for (target, label) in MAPPING_TARGETS {
            if let Ok(option) = document.create_element("option") {
                let _ = option.set_attribute("value", target);
                option.set_text_content(Some(label));
                if *target == suggested {
                    let _ = option.set_attribute("selected", "");
                }
                let _ = select.append_child(&option);
            }
        }
        let _ = cell.append_child(&select);
        let _ = row.append_child(&cell);
        let _ = rows.append_child(&row);
    }

    let columns = preview.columns.clone();
    let apply_page = Rc::clone(page);
    let apply_dialog = dialog.clone();
    let apply = document.get_element_by_id("mapping-apply").map(|button| {
        EventListener::once(&button, "click", move |_| {
            let document = &apply_page.document;
            let renames: Vec<(String, String)> = columns
                .iter()
                .enumerate()
                .filter_map(|(column_idx, column)| {
                    let select = document
                        .get_element_by_id(&format!("mapping-{column_idx}"))?
                        .dyn_into::<HtmlSelectElement>()
                        .ok()?;
                    Some((column.clone(), select.value()))
                })
                .collect();
            let mapping = ColumnMapping { renames };
            if let Some(signature) = &signature {
                let mut remembered = load();
                remembered.insert(signature.clone(), mapping.clone());
                save(&remembered);
            }
            apply_dialog.close();
            apply_page.analyse_file_list(vec![file.clone()], Some(mapping));
        })
    });
    let cancel_dialog = dialog.clone();
    let cancel = document
        .get_element_by_id("mapping-cancel")
        .map(|button| EventListener::once(&button, "click", move |_| cancel_dialog.close()));
    // The listeners live until the dialog is next opened, which replaces them.
    LISTENERS.with(|listeners| *listeners.borrow_mut() = (apply, cancel));
    let _ = dialog.show_modal();
}

thread_local! {
    /// The dialog's current button listeners (dropping them removes them).
    static LISTENERS: std::cell::RefCell<(Option<EventListener>, Option<EventListener>)> =
        const { std::cell::RefCell::new((None, None)) };
}
