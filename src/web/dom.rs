//! Putting text into the page: the one way log-derived text reaches the DOM
//! (`textContent`, never HTML), shared by the page, the live panel and the exports; the
//! CLI's flags in the core's sentences become the page's fields on the way
//! ([`super::wording`]).

use web_sys::Document;

/// Sets the text of element `#id` (nothing when the page has no such element).
pub fn set_text(document: &Document, id: &str, text: &str) {
    if let Some(element) = document.get_element_by_id(id) {
        element.set_text_content(Some(&super::wording::for_page(text)));
    }
}

/// Replaces the items of list `#id` with one `<li>` of text per item.
pub fn fill_list(document: &Document, id: &str, items: impl Iterator<Item = String>) {
    let Some(list) = document.get_element_by_id(id) else {
        return;
    };
    list.set_text_content(None);
    for item in items {
        if let Ok(list_item) = document.create_element("li") {
            list_item.set_text_content(Some(&super::wording::for_page(&item)));
            let _ = list.append_child(&list_item);
        }
    }
}
