use ecr_macros::ecr_method;

ecr_method!(s = 3);

fn main() {}
